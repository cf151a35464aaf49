import numpy as np
import pytest

from negobs_gym.detector.config import Hdl64FeatureConfig
from negobs_gym.detector.hdl64 import extract_hdl64_pairs
from negobs_gym.detector.loaders import (
    assign_rings,
    azimuth_columns,
    cloud_to_scan,
    column_span,
    load_kitti_bin,
    recover_rings,
    ring_cloud_to_scan,
    ros_to_sensor_frame,
    sensor_to_ros_frame,
)
from negobs_gym.detector.synthetic import HDL64_ELEVATION_DEG, Hole, synthetic_scan
from negobs_gym.errors import ScanError


@pytest.fixture(scope="module")
def analytic():
    # azimuths at the loader's bin centres (0.09 deg bins) so the round trip is exact
    az = -np.pi + (np.arange(4000) + 0.5) * 2 * np.pi / 4000
    return synthetic_scan(
        "hdl64",
        np.radians(HDL64_ELEVATION_DEG),
        az,
        np.eye(3),
        np.array([0.0, 0.0, 2.2]),
        [Hole.ahead(8.0, 1.0, 1.0, 0.8)],
    )


def _cloud(scan):
    p = scan.points_sensor
    ok = scan.valid
    ring = np.broadcast_to(np.arange(scan.shape[0])[:, None], scan.shape)[ok]
    return p[ok], ring


def test_ring_cloud_round_trip(analytic):
    xyz, ring = _cloud(analytic)
    cloud = np.column_stack([xyz, np.ones(len(xyz)), ring])
    rng = np.random.default_rng(0)
    scan = ring_cloud_to_scan(
        rng.permutation(cloud), analytic.elevation_rad, sensor="hdl64", translation_m=[0, 0, 2.2]
    )
    assert scan.shape == analytic.shape
    np.testing.assert_allclose(scan.ranges_m, analytic.ranges_m, equal_nan=True)
    assert np.nanmax(scan.intensity) == 1.0


def test_kitti_bin_round_trip_recovers_rings_and_pairs(analytic, tmp_path):
    xyz, _ring = _cloud(analytic)  # laser by laser, each in azimuth order: KITTI's point order
    kitti = np.column_stack([xyz[:, 1], -xyz[:, 0], xyz[:, 2], np.zeros(len(xyz))])
    path = tmp_path / "000000.bin"
    kitti.astype(np.float32).tofile(path)
    scan = load_kitti_bin(path, analytic.elevation_rad, translation_m=[0, 0, 2.2])
    seen = analytic.valid.any(axis=1)  # lasers above the horizon return nothing: no ring to recover
    assert scan.shape == (seen.sum(), analytic.shape[1])
    np.testing.assert_allclose(scan.elevation_rad, analytic.elevation_rad[seen], atol=1e-6)
    np.testing.assert_allclose(scan.ranges_m, analytic.ranges_m[seen], rtol=1e-6, equal_nan=True)
    fp = extract_hdl64_pairs(scan, Hdl64FeatureConfig())
    ref = extract_hdl64_pairs(analytic, Hdl64FeatureConfig())
    assert len(fp) == len(ref) > 0


def test_point_order_survives_another_units_table(analytic):
    """Rings of a unit whose lasers sit 0.25 deg off the table: the point order gets every ring,
    the nearest table entry mis-rings points (the table is one unit's calibration)."""
    el = analytic.elevation_rad + np.radians(0.25) * np.where(np.arange(64) % 2, 1.0, -1.0)
    other = synthetic_scan("hdl64", el, analytic.azimuth_rad, np.eye(3), np.array([0, 0, 2.2]), [])
    xyz, ring = _cloud(other)
    by_order = assign_rings(xyz, analytic.elevation_rad)
    assert by_order.source == "point_order"
    seen = np.flatnonzero(other.valid.any(axis=1))
    np.testing.assert_array_equal(seen[by_order.ring], ring)
    np.testing.assert_allclose(by_order.elevation_rad, el[seen], atol=1e-9)
    assert (recover_rings(xyz, analytic.elevation_rad) != ring).mean() > 0.1
    firing = np.transpose(other.points_sensor, (1, 0, 2))[other.valid.T]  # column by column
    assert assign_rings(firing, analytic.elevation_rad).source == "elevation_table"


def test_recover_rings_nearest_entry():
    el = np.radians([-10.0, -5.0, 0.0])
    pts = np.array([[0, 10, 10 * np.tan(np.radians(-6.0))], [0, 10, 10 * np.tan(np.radians(-8.0))]])
    assert recover_rings(pts, el).tolist() == [1, 0]


def test_duplicates_keep_nearest_deterministically():
    xyz = np.array([[0, 10.0, 0], [0, 5.0, 0], [0, 7.0, 0]])
    scan = cloud_to_scan(xyz, np.zeros(3, int), np.array([0.0]), sensor="s", azimuth_resolution_deg=1)
    assert np.nanmin(scan.ranges_m) == 5.0 and (~np.isnan(scan.ranges_m)).sum() == 1


def test_bad_clouds_rejected(tmp_path):
    with pytest.raises(ScanError, match="NaN or inf"):
        ring_cloud_to_scan(np.array([[np.nan, 0, 0, 0, 0]]), np.zeros(1), sensor="s")
    with pytest.raises(ScanError, match="ring indices"):
        ring_cloud_to_scan(np.array([[1.0, 0, 0, 0, 3]]), np.zeros(2), sensor="s")
    with pytest.raises(ScanError, match="shape"):
        ring_cloud_to_scan(np.zeros((3, 2)), np.zeros(2), sensor="s")
    bad = tmp_path / "bad.bin"
    np.zeros(5, np.float32).tofile(bad)
    with pytest.raises(ScanError, match="multiple of 4"):
        load_kitti_bin(bad, np.zeros(2))


def test_empty_cloud_gives_scan_without_returns():
    scan = ring_cloud_to_scan(np.empty((0, 5)), np.array([-0.1, 0.0]), sensor="s")
    assert np.isnan(scan.ranges_m).all()


def test_centred_columns_keep_a_fixed_angle_scanners_returns_apart():
    """A LUX fires at multiples of 0.25 deg: on column edges a float32 coordinate's last bit picks
    the side, and neighbouring returns share a column; centred columns hold one each."""
    firing = np.arange(-220, 221)  # -55 .. +55 deg in 0.25 deg steps
    az = np.radians(firing * 0.25)
    xyz = np.column_stack([10 * np.sin(az), 10 * np.cos(az), np.full(az.size, -0.5)]).astype(np.float32)
    edges, n_cols = azimuth_columns(xyz, 0.25)
    assert n_cols == 1440 and np.unique(edges).size < az.size - 50  # returns lost to shared columns
    centred, _ = azimuth_columns(xyz, 0.25, centred=True)
    assert np.array_equal(centred, firing + 720)
    one_layer = np.zeros(az.size, int)
    scan = cloud_to_scan(
        xyz, one_layer, np.radians([-0.4]), sensor="lux", azimuth_resolution_deg=0.25, columns_centred=True
    )
    assert int(scan.valid.sum()) == az.size
    np.testing.assert_allclose(scan.azimuth_rad[firing + 720], az, atol=1e-12)
    # the +-180 deg column is one column, centred on the seam
    back = np.array([[0.0, -5.0, 0.0], [1e-6, -5.0, 0.0], [-1e-6, -5.0, 0.0]])
    assert set(azimuth_columns(back, 0.25, centred=True)[0]) == {0}


def test_cropped_columns_are_the_span_of_the_returns():
    """``crop_columns``: the range image from the first to the last column with a return, equal to
    the revolution's columns there, which hold every return; none outside it."""
    rng = np.random.default_rng(0)
    az = rng.uniform(np.radians(-55), np.radians(55), 400)
    xyz = np.column_stack([10 * np.sin(az), 10 * np.cos(az), rng.uniform(-1, 0, az.size)])
    ring, elevation = rng.integers(0, 4, az.size), np.radians([-1.2, -0.4, 0.4, 1.2])
    kwargs = {"sensor": "lux", "intensity": rng.uniform(0, 1, az.size), "azimuth_resolution_deg": 0.25}
    full = cloud_to_scan(xyz, ring, elevation, columns_centred=True, **kwargs)
    crop = cloud_to_scan(xyz, ring, elevation, columns_centred=True, crop_columns=True, **kwargs)
    first, stop = column_span(azimuth_columns(xyz, 0.25, centred=True)[0], 1440)
    assert stop - first == crop.shape[1] <= 441 and full.shape[1] == 1440
    np.testing.assert_array_equal(crop.ranges_m, full.ranges_m[:, first:stop])
    np.testing.assert_array_equal(crop.intensity, full.intensity[:, first:stop])
    np.testing.assert_array_equal(crop.azimuth_rad, full.azimuth_rad[first:stop])
    np.testing.assert_array_equal(crop.points_vehicle, full.points_vehicle[:, first:stop])
    assert int(crop.valid.sum()) == int(full.valid.sum())
    assert np.isfinite(crop.ranges_m[:, 0]).any() and np.isfinite(crop.ranges_m[:, -1]).any()
    # returns on both sides of the seam behind (+-178.9 deg): the span does not wrap, it runs the
    # long way round, from the first column to the last; no return keeps the whole revolution
    behind = np.array([[0.1, -5.0, 0.0], [-0.1, -5.0, 0.0]])
    scan = cloud_to_scan(behind, np.zeros(2), elevation[:1], sensor="s", crop_columns=True)
    assert int(scan.valid.sum()) == 2 and 3900 < scan.shape[1] < 4000
    empty = cloud_to_scan(np.empty((0, 3)), np.zeros(0), elevation[:1], sensor="s", crop_columns=True)
    assert empty.shape == (1, 4000)


def test_sensor_to_ros_frame_inverts_ros_to_sensor_frame():
    ros = np.array([[5.0, 1.0, -0.5], [0.0, -2.0, 0.3]])  # x forward, y left
    sensor = ros_to_sensor_frame(ros)
    np.testing.assert_array_equal(sensor, [[-1.0, 5.0, -0.5], [2.0, 0.0, 0.3]])  # X right, Y forward
    np.testing.assert_array_equal(sensor_to_ros_frame(sensor), ros)
