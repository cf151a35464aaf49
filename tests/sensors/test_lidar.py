import warnings

import numpy as np
import pytest

from negobs_gym.core.pose import Pose
from negobs_gym.errors import InterfaceError
from negobs_gym.sensors import NoiseConfig, hdl64e_s2, hdl64e_s2_nominal, paper_n_rig
from negobs_gym.sensors.lidar import frame_noise_key, scan
from negobs_gym.sensors.noise import apply_keyed_noise
from negobs_gym.sensors.raycast.pybullet_backend import PyBulletCaster
from tests.sensors.helpers import static_box

OFF = NoiseConfig(enabled=False)


@pytest.mark.parametrize("model", [hdl64e_s2, hdl64e_s2_nominal])
def test_flat_ring_radii(client, model):
    static_box(client, [100, 100, 1], [0, 0, -1])
    mount = paper_n_rig(hdl64=model()).mount("hdl64")
    s = scan(mount, PyBulletCaster(client), Pose(), noise=OFF)
    pts = s.points_vehicle
    radius = np.hypot(pts[..., 0], pts[..., 1])
    beta = np.pi / 2 + s.elevation_rad  # nadir angle
    down = s.elevation_rad < -0.01
    expected = 2.2 * np.tan(beta[down])
    with warnings.catch_warnings():  # lasers with no return (beyond max range) give all-NaN rows
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(radius[down], axis=1)
    ok = expected < 100
    assert ok.sum() >= 45
    assert np.all(np.abs(med[ok] - expected[ok]) < 0.01)


def test_side_spacing_and_pit(client):
    # ground with a 1 x 1 x 0.8 m pit centred 8 m ahead: four slabs around it plus the floor.
    static_box(client, [100, 100, 1], [0, 0, -1.8])
    static_box(client, [100, 46, 0.4], [0, 8.5 + 46, -0.4])
    static_box(client, [100, 46, 0.4], [0, 7.5 - 46, -0.4])
    static_box(client, [49.5, 0.5, 0.4], [-0.5 - 49.5, 8, -0.4])
    static_box(client, [49.5, 0.5, 0.4], [0.5 + 49.5, 8, -0.4])
    rig = paper_n_rig()
    caster = PyBulletCaster(client)
    s64 = scan(rig.mount("hdl64"), caster, Pose(), noise=OFF)
    p64 = s64.points_vehicle
    in_pit = (np.abs(p64[..., 0]) < 0.45) & (np.abs(p64[..., 1] - 8) < 0.45)
    # rings pass through the pit footprint (radius 7.55-8.45 m) but leave no ground-level return there
    ring_r = 2.2 * np.tan(np.pi / 2 + s64.elevation_rad)
    assert np.any((ring_r > 7.55) & (ring_r < 8.45))
    assert not np.any(in_pit & (p64[..., 2] > -0.05))
    # side HDL-32: radial spacing at 10 m along one laser line vs HDL-64 ring spacing there
    sl = scan(rig.mount("hdl32_left"), caster, Pose(), noise=OFF)
    pl = sl.points_vehicle
    ground = np.abs(pl[..., 2]) < 0.05
    spacings = []
    for k in range(pl.shape[0]):
        y = np.sort(pl[k][ground[k] & (np.abs(pl[k][:, 1] - 10) < 1)][:, 1])
        if y.size > 2:
            spacings.append(np.median(np.diff(y)))
    behind = (np.abs(p64[..., 0]) < 0.3) & (p64[..., 1] < 0)  # columns looking straight behind
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rows = np.nanmedian(np.where(behind, np.hypot(p64[..., 0], p64[..., 1]), np.nan), axis=1)
    r64 = np.sort(rows[np.isfinite(rows)])
    gap64 = np.diff(r64)[np.argmin(np.abs(r64[:-1] - 10))]
    assert 0.2 < gap64 < 2.0  # HDL-64 ring gap near 10 m (calibrated table: 0.30 m)
    assert spacings and max(spacings) <= gap64 / 2
    # range jump along a left HDL-32 laser line crossing the pit
    rng_jumps = np.abs(np.diff(sl.ranges_m, axis=1))
    crosses = (np.abs(pl[..., 0]) < 0.5) & (np.abs(pl[..., 1] - 8) < 0.6) & (pl[..., 2] < -0.05)
    assert crosses.any() and np.nanmax(rng_jumps[crosses.any(axis=1)]) > 0.3


def test_noise_deterministic(client):
    static_box(client, [100, 100, 1], [0, 0, -1])
    mount = paper_n_rig().mount("hdl64")
    a = scan(mount, PyBulletCaster(client), Pose(), rng=np.random.default_rng(3))
    b = scan(mount, PyBulletCaster(client), Pose(), rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a.ranges_m, b.ranges_m)


def test_noise_without_a_generator_is_refused_by_name():
    with pytest.raises(InterfaceError, match=r"^rng: noise is enabled") as error:
        frame_noise_key(3, NoiseConfig())
    assert isinstance(error.value, TypeError)
    assert frame_noise_key(None, OFF) == 0  # no noise: no generator needed


def test_exclude_own_body(client):
    static_box(client, [100, 100, 1], [0, 0, -1])
    car = static_box(client, [1.5, 3, 0.8], [0, 0, 0.8])
    mount = paper_n_rig().mount("hdl64")
    with_car = scan(mount, PyBulletCaster(client), Pose(), noise=OFF)
    without = scan(mount, PyBulletCaster(client, exclude_body_ids=[car]), Pose(), noise=OFF)
    assert np.nanmin(with_car.ranges_m) < 2.0
    assert np.nanmin(without.ranges_m) > 2.0


def test_row_rotation_and_ray_normalisation_match_the_matrix_forms_row_by_row():
    from scipy.spatial.transform import Rotation

    from negobs_gym.errors import ScanError
    from negobs_gym.sensors.lidar import rotate_planes, rotate_rows
    from negobs_gym.sensors.raycast.base import check_rays

    rng = np.random.default_rng(3)
    d = rng.normal(size=(1000, 3))
    rotation = Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix()
    rotated = rotate_rows(d, rotation)
    np.testing.assert_allclose(rotated, d @ rotation.T, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rotate_rows(d[::7], rotation), rotated[::7])  # batch-independent
    _, unit = check_rays(np.zeros_like(d), d, 100.0)
    np.testing.assert_array_equal(unit, d / np.linalg.norm(d, axis=1)[:, None])
    _, unit32 = check_rays(np.zeros_like(d), d, 100.0, dtype=np.float32)
    assert unit32.dtype == np.float32
    np.testing.assert_array_equal(unit32, unit.astype(np.float32))  # rounded once, from float64
    x, y, z = (np.ascontiguousarray(d[:, k]) for k in range(3))
    index = rng.permutation(1000)[:300]
    np.testing.assert_array_equal(rotate_planes(x, y, z, rotation, index), rotated[index])
    d[4] = 0.0
    with pytest.raises(ScanError, match="non-zero"):
        check_rays(np.zeros_like(d), d, 100.0)
    d[9] = np.nan  # a NaN anywhere is named even after a zero row
    with pytest.raises(ScanError, match="finite"):
        check_rays(np.zeros_like(d), d, 100.0, dtype=np.float32)


def test_keyed_noise_of_a_ray_does_not_depend_on_the_other_rays_hitting():
    # noise is drawn for the hits only: a ray's draw must come from its key and index alone
    rng = np.random.default_rng(4)
    ranges = rng.uniform(2.0, 60.0, 5000)
    index = rng.permutation(20000)[:5000]
    cfg = NoiseConfig(dropout_prob=0.05)
    full = apply_keyed_noise(ranges, index, cfg, key=77)
    gappy = ranges.copy()
    gappy[rng.random(5000) < 0.4] = np.nan
    got = apply_keyed_noise(gappy, index, cfg, key=77)
    hit = ~np.isnan(gappy)
    np.testing.assert_array_equal(got[hit], full[hit])
    assert np.isnan(got[~hit]).all()
    assert 0.02 < np.isnan(full).mean() < 0.08  # dropout drawn as configured
    assert 0.005 < np.nanstd(full - ranges) < 0.05  # range noise present, at the configured scale
