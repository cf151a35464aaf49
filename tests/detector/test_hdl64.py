import numpy as np
import pytest

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.config import Hdl64FeatureConfig
from negobs_gym.detector.geometry import radial_resolution
from negobs_gym.detector.hdl64 import (
    FALL,
    RISE,
    edge_labels,
    extract_hdl64_pairs,
    find_bumps,
    max_filter_ranges,
    point_density,
    ring_gap_threshold,
    trace_pairs,
)
from negobs_gym.detector.synthetic import Hole, hdl64_scan
from negobs_gym.errors import ConfigError

CFG = Hdl64FeatureConfig()


@pytest.fixture(scope="module")
def hole8():
    return hdl64_scan([Hole.ahead(8.0, 1.0, 1.0, 0.8)])


def test_max_filter_radius_and_nan():
    r = np.array([[1.0, 1, 1, 1, 5, 1, 1, 1, 1, np.nan, 1]])
    f = max_filter_ranges(r, 3)
    np.testing.assert_array_equal(f[0, :8], [1, 5, 5, 5, 5, 5, 5, 5])
    assert f[0, 8] == 1 and np.isnan(f[0, 9])


def test_edges_and_bump_on_step_profile():
    r = np.array([[5.0] * 10 + [6.0] * 10 + [5.0] * 10])
    lab = edge_labels(r, 0.2, -0.2, 2)
    assert set(np.nonzero(lab[0] == RISE)[0]) == {8, 9, 10, 11}
    assert set(np.nonzero(lab[0] == FALL)[0]) == {18, 19, 20, 21}
    row, start, end = find_bumps(lab)
    assert row.tolist() == [0] and start.tolist() == [11] and end.tolist() == [18]


def test_small_steps_are_not_edges():
    r = np.array([[5.0] * 10 + [5.15] * 10])
    assert not edge_labels(r, 0.2, -0.2, 2).any()


def test_density_threshold_eq10_and_back_wall_density(hole8):
    el = np.sort(hole8.elevation_rad)
    t = ring_gap_threshold(el, 2.2, 0.55)
    beta = np.pi / 2 + el
    dr = radial_resolution(2.2, beta[10], beta[10] - beta[9])
    dr_next = radial_resolution(2.2, beta[11], beta[11] - beta[10])
    assert t[10] == pytest.approx(0.55 * max(dr, dr_next))
    assert np.isnan(t[-1])  # laser above the horizon: no ring
    pts = hole8.points_vehicle
    k = int(np.argmin(np.abs(hole8.azimuth_rad)))
    wall = np.nonzero(np.isclose(pts[:, k, 1], 9.0) & (pts[:, k, 2] < -0.01))[0]
    ground = np.array([10, 15])
    rows = np.concatenate([wall, ground])
    d = point_density(pts, rows, np.full(rows.size, k), t[rows], 6, 2)
    assert d[: wall.size].min() >= 2  # back-wall points have other lasers close by
    np.testing.assert_array_equal(d[wall.size :], 1)  # flat ground: only its own laser


def test_trace_pairs_finds_nearest_lower_and_upper_laser(hole8):
    pts, valid = hole8.points_vehicle, hole8.valid
    k = int(np.argmin(np.abs(hole8.azimuth_rad)))
    valid = valid.copy()
    valid[20, :] = False  # laser 20 dropped: A must come from laser 19
    a, c = trace_pairs(pts, valid, hole8.azimuth_rad, np.array([21]), np.array([k]), np.radians(0.09))
    np.testing.assert_allclose(a[0], pts[19, k])
    np.testing.assert_allclose(c[0], pts[22, k])


@pytest.mark.parametrize("distance_m", [8.0, 12.0])
def test_hole_yields_pairs_on_near_and_far_rim(distance_m):
    scan = hdl64_scan([Hole.ahead(distance_m, 1.0, 1.0, 0.8)])
    fp = extract_hdl64_pairs(scan, CFG)
    assert len(fp) >= 20
    # A on the ground just before the near rim, B on the back wall (far rim)
    assert np.all((fp.a_m[:, 1] > distance_m - 0.6) & (fp.a_m[:, 1] <= distance_m))
    # B inside the hole below the ground, mostly on the back wall (a few on the side walls)
    assert np.all((fp.b_m[:, 1] > distance_m) & (fp.b_m[:, 1] <= distance_m + 1.0 + 1e-9))
    assert np.mean(np.isclose(fp.b_m[:, 1], distance_m + 1.0)) >= 0.8
    assert np.all(np.abs(fp.a_m[:, 0]) <= 0.5 + 1e-9) and np.all(fp.b_m[:, 2] < 0)
    assert np.all(fp.c_m[:, 2] > fp.b_m[:, 2])


def test_flat_plane_with_noise_yields_at_most_two_pairs():
    for seed in range(3):
        scan = hdl64_scan(noise_sigma_m=0.02, rng=np.random.default_rng(seed))
        assert len(extract_hdl64_pairs(scan, CFG)) <= 2


def test_strict_pair_test_rejects_hole_pairs():
    from negobs_gym.detector.config import PairTestConfig

    scan = hdl64_scan([Hole.ahead(8.0, 1.0, 1.0, 0.8)])
    cfg = Hdl64FeatureConfig(pair_test=PairTestConfig(w_min_m=1.5))
    assert len(extract_hdl64_pairs(scan, cfg)) == 0


def test_empty_and_no_return_scans():
    empty = StructuredScan(
        "hdl64", np.empty((64, 0)), np.empty(0), np.linspace(-0.4, 0, 64), translation_m=[0, 0, 2]
    )
    assert len(extract_hdl64_pairs(empty, CFG)) == 0
    nan = StructuredScan(
        "hdl64",
        np.full((4, 5), np.nan),
        np.arange(5.0) / 10,
        np.linspace(-0.4, 0, 4),
        translation_m=[0, 0, 2],
    )
    assert len(extract_hdl64_pairs(nan, CFG)) == 0


def test_sensor_below_ground_rejected():
    scan = StructuredScan("hdl64", np.ones((2, 3)), np.arange(3.0), np.array([-0.3, -0.2]))
    with pytest.raises(ValueError, match="sensor height"):
        extract_hdl64_pairs(scan, CFG)


def test_config_validation():
    with pytest.raises(ConfigError, match="edge_fall_m"):
        Hdl64FeatureConfig(edge_fall_m=0.2)
    with pytest.raises(ConfigError, match="max_filter_radius"):
        Hdl64FeatureConfig(max_filter_radius=0)
