import math

import numpy as np
import pytest

from negobs_gym.core import Pose, StructuredScan
from negobs_gym.errors import ScanError


def _scan(ranges=None, **kw):
    el = np.radians([-10.0, -5.0])
    az = np.radians([-10.0, 0.0, 10.0])
    if ranges is None:
        ranges = np.full((2, 3), 5.0)
    return StructuredScan("s", ranges, az, el, **kw)


def test_points_follow_the_documented_ray_convention():
    scan = _scan()
    p = scan.points_sensor
    # azimuth 0 points along +Y, positive azimuth towards +X, negative elevation points down
    assert np.allclose(
        p[0, 1], 5.0 * np.array([0.0, math.cos(math.radians(-10)), math.sin(math.radians(-10))])
    )
    assert p[0, 2, 0] > 0 and p[0, 0, 0] < 0
    assert np.allclose(np.linalg.norm(p, axis=-1), 5.0)


def test_extrinsics_map_sensor_to_vehicle_and_pose_to_world():
    scan = _scan(translation_m=[0.0, 0.0, 2.2], pose=Pose(x=10.0, yaw=math.pi))
    assert np.allclose(scan.points_vehicle[..., 2], scan.points_sensor[..., 2] + 2.2)
    world = scan.points_world()
    assert np.allclose(world[..., 1], -scan.points_vehicle[..., 1])
    assert np.allclose(world[..., 0], 10.0 - scan.points_vehicle[..., 0])


def test_nan_is_no_return_and_arrays_are_read_only():
    r = np.full((2, 3), 5.0)
    r[1, 2] = np.nan
    scan = _scan(r)
    assert not scan.valid[1, 2] and scan.valid.sum() == 5
    assert np.isnan(scan.points_vehicle[1, 2]).all()
    with pytest.raises(ValueError):
        scan.ranges_m[0, 0] = 1.0
    r[0, 0] = 99.0  # the scan keeps its own copy
    assert scan.ranges_m[0, 0] == 5.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"ranges": np.full((2, 3), np.inf)}, "inf"),
        ({"ranges": np.full((2, 3), -1.0)}, "negative"),
        ({"ranges": np.full((3, 3), 1.0)}, "does not match"),
        ({"ranges": np.ones(6)}, "2-D"),
        ({"rotation": np.ones((3, 3))}, "orthonormal"),
        ({"translation_m": [0.0, np.nan, 0.0]}, "translation"),
        ({"intensity": np.ones((1, 3))}, "intensity"),
    ],
)
def test_bad_scans_raise_scan_error_naming_the_problem(kwargs, match):
    with pytest.raises(ScanError, match=match):
        _scan(**kwargs)


def test_unsorted_azimuths_and_empty_scans():
    with pytest.raises(ScanError, match="strictly increasing"):
        StructuredScan("s", np.ones((1, 3)), [0.0, 0.2, 0.1], [0.0])
    empty = StructuredScan("s", np.empty((4, 0)), [], [0.0, 0.1, 0.2, 0.3])
    assert empty.shape == (4, 0) and empty.points_vehicle.shape == (4, 0, 3)


def test_vehicle_points_are_paper_n_eq_9_for_any_rotation_and_nan_stays_nan():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(5)
    rotation = Rotation.from_euler("xyz", rng.uniform(-np.pi, np.pi, 3)).as_matrix()
    ranges = rng.uniform(1.0, 60.0, (2, 3))
    ranges[1, 0] = np.nan
    scan = _scan(ranges, rotation=rotation, translation_m=[0.3, -1.2, 2.0])
    expected = scan.points_sensor @ scan.rotation.T + scan.translation_m  # Eq. 9: R p + T
    np.testing.assert_allclose(scan.points_vehicle, expected, rtol=0, atol=1e-12)
    assert np.isnan(scan.points_vehicle[1, 0]).all() and np.isfinite(scan.points_vehicle[0]).all()
    # a second scan of the same geometry (the cached rotated directions) gives the same points
    again = _scan(ranges, rotation=rotation, translation_m=[0.3, -1.2, 2.0])
    np.testing.assert_array_equal(again.points_vehicle, scan.points_vehicle)


def test_points_vehicle_equal_range_times_rotated_direction_plus_translation_bit_for_bit():
    rng = np.random.default_rng(4)
    el = np.radians(np.linspace(-25.0, 2.0, 7))
    az = np.radians(np.linspace(-180.0, 179.0, 40))
    ranges = rng.uniform(0.5, 80.0, (7, 40))
    ranges[rng.random((7, 40)) < 0.2] = np.nan
    c, s = math.cos(0.3), math.sin(0.3)
    rot = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    scan = StructuredScan("s", ranges, az, el, rotation=rot, translation_m=[0.4, -1.1, 2.2])
    planes = scan.directions_vehicle
    want = np.stack([ranges * planes[a] + scan.translation_m[a] for a in range(3)], axis=-1)
    assert np.array_equal(scan.points_vehicle, want, equal_nan=True)


def test_column_motion_moves_each_columns_points_and_origin():
    # column 0 fired when the vehicle was 0.5 m behind, column 2 when it was turned 90 deg left
    motion = np.zeros((3, 3, 4))
    motion[:, :, :3] = np.eye(3)
    motion[0, 1, 3] = -0.5
    motion[2, :, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    still = _scan(translation_m=[0.0, 1.0, 2.0])
    moved = _scan(translation_m=[0.0, 1.0, 2.0], column_motion=motion)
    p, q = still.points_vehicle, moved.points_vehicle
    np.testing.assert_array_equal(q[:, 1], p[:, 1])
    np.testing.assert_allclose(q[:, 0], p[:, 0] - [0.0, 0.5, 0.0])
    np.testing.assert_allclose(q[:, 2], np.stack([-p[:, 2, 1], p[:, 2, 0], p[:, 2, 2]], axis=-1))
    np.testing.assert_allclose(
        moved.origins_vehicle([0, 1, 2]), [[0.0, 0.5, 2.0], [0.0, 1.0, 2.0], [-1.0, 0.0, 2.0]]
    )
    np.testing.assert_array_equal(still.origins_vehicle([0, 2]), [[0.0, 1.0, 2.0]] * 2)
    np.testing.assert_array_equal(moved.ranges_m, still.ranges_m)  # the range image as recorded
    # any motions: M p + m per column (the compiled pass against numpy), no return stays none
    rng = np.random.default_rng(8)
    ranges = rng.uniform(1.0, 60.0, (2, 3))
    ranges[0, 1] = np.nan
    anything = rng.normal(size=(3, 3, 4))
    plain, shifted = _scan(ranges), _scan(ranges, column_motion=anything)
    want = np.einsum("cij,lcj->lci", anything[:, :, :3], plain.points_vehicle) + anything[:, :, 3]
    np.testing.assert_allclose(shifted.points_vehicle, want, rtol=0, atol=1e-12)
    assert np.isnan(shifted.points_vehicle[0, 1]).all() and np.isfinite(shifted.points_vehicle[1]).all()
    for bad in (np.zeros((2, 3, 4)), np.full((3, 3, 4), np.nan)):
        with pytest.raises(ScanError, match="column_motion must be 3 finite 3x4 motions"):
            _scan(column_motion=bad)
