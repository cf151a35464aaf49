import numpy as np
import pytest

from negobs_gym.detector.synthetic import Hole, cast_ranges, hdl32_side_scan, hdl64_scan
from negobs_gym.errors import ConfigError


def test_plane_and_hole_hits():
    o = np.array([0.0, 0.0, 2.0])
    dirs = np.array([[0, 1, -0.25], [0, 1, -0.2], [0, 1, 0.1]], dtype=float)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    r = cast_ranges(o, dirs, [Hole(x0_m=-1, x1_m=1, y0_m=9, y1_m=11, depth_m=0.5)])
    p = o + r[:, None] * dirs
    assert p[0] == pytest.approx([0, 8, 0])  # plane before the hole
    assert p[1, 1] == pytest.approx(11.0)  # back wall of the hole
    assert -0.5 < p[1, 2] < 0
    assert np.isnan(r[2])  # sky


def test_hole_floor_hit():
    o = np.array([0.0, 0.0, 2.0])
    d = np.array([[0.0, 0.5, -1.0]]) / np.sqrt(1.25)
    r = cast_ranges(o, d, [Hole(x0_m=-1, x1_m=1, y0_m=0.5, y1_m=3, depth_m=0.4)])
    assert (o + r[0] * d[0])[2] == pytest.approx(-0.4)


def test_side_rig_lasers_sweep_near_to_far():
    s = hdl32_side_scan()
    p = s.points_vehicle[16]
    front = (s.azimuth_rad > -np.pi / 2) & (s.azimuth_rad < -0.2)
    y = p[front, 1]
    assert np.all(np.diff(y) > 0)


def test_noise_needs_rng_and_is_deterministic():
    with pytest.raises(ConfigError, match="rng"):
        hdl64_scan(n_columns=100, noise_sigma_m=0.02)
    a = hdl64_scan(n_columns=100, noise_sigma_m=0.02, rng=np.random.default_rng(3))
    b = hdl64_scan(n_columns=100, noise_sigma_m=0.02, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a.ranges_m, b.ranges_m)


def test_bad_hole_rejected():
    with pytest.raises(ConfigError, match="depth_m"):
        Hole(x0_m=0, x1_m=1, y0_m=0, y1_m=1, depth_m=0)
