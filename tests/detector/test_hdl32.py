import numpy as np
import pytest

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.config import Hdl32FeatureConfig
from negobs_gym.detector.hdl32 import (
    compensate_missing,
    density_threshold,
    extract_hdl32_pairs,
    ground_hit_distance,
    next_point,
    range_jumps,
    same_laser_density,
)
from negobs_gym.detector.synthetic import Hole, hdl32_side_scan
from negobs_gym.errors import ConfigError

CFG = Hdl32FeatureConfig()


def test_compensation_only_where_ordered():
    r = np.array([[5.0, 6.0, np.nan, 8.0], [5.0, 6.0, 7.1, 8.0], [5.0, 6.0, 6.9, 8.0]])
    c = compensate_missing(r)
    assert c[0, 2] == pytest.approx(7.1)  # only laser 1 neighbours laser 0
    r2 = r.copy()
    r2[1, 2] = 20.0  # neighbour estimate not between 6 and 8: stays missing
    assert np.isnan(compensate_missing(r2)[0, 2])
    np.testing.assert_array_equal(c[1:], r[1:])


def test_range_jump_second_difference():
    r = np.array([[5.0, 5.1, 5.2, 5.3, 6.0, 6.02]])
    g = np.arange(6.0)[None]
    j = range_jumps(r, g, 0.3, 1)
    # r_diff at 4 = 0.7 - 0.1 = 0.6 > 0.3; at 5 = 0.02 - 0.7 < 0
    assert j[0].tolist() == [False, False, False, False, True, False]
    assert not range_jumps(r, g[:, ::-1], 0.3, 1).any()  # far -> near direction is skipped


def test_same_laser_density_counts_points_within_radius():
    pts = np.zeros((1, 5, 3))
    pts[0, :, 1] = [0.0, 0.1, 0.2, 0.5, 0.55]
    d = same_laser_density(pts, 0.15, 4)
    assert d[0].tolist() == [2, 3, 2, 2, 2]


def test_next_point_skips_back_wall_neighbourhood():
    pts = np.zeros((1, 5, 3))
    pts[0, :, 2] = [0.0, 0.05, 0.1, 0.2, 0.3]
    c = next_point(pts, np.array([0]), np.array([0]), 1, 0.15, 4)
    assert c[0, 2] == pytest.approx(0.2)
    assert next_point(pts, np.array([0]), np.array([0]), 1, 0.0, 4)[0, 2] == pytest.approx(0.05)


def test_ground_hit_distance_matches_plane():
    s = hdl32_side_scan()
    g = ground_hit_distance(s, 2.0)
    p = s.points_vehicle
    d = np.hypot(p[..., 0] - s.translation_m[0], p[..., 1] - s.translation_m[1])
    ok = np.isfinite(d)
    np.testing.assert_allclose(g[ok], d[ok], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("distance_m", [8.0, 12.0])
def test_hole_yields_pairs_from_side_sensors(side, distance_m):
    scan = hdl32_side_scan([Hole.ahead(distance_m, 1.0, 1.0, 0.8)], side=side)
    fp = extract_hdl32_pairs(scan, CFG)
    assert len(fp) >= 2
    assert np.all((fp.a_m[:, 1] > distance_m - 0.5) & (fp.a_m[:, 1] <= distance_m))
    # B inside the hole below ground: on the back wall (far rim) or a side wall near it
    assert np.all((fp.b_m[:, 1] > distance_m + 0.5) & (fp.b_m[:, 1] <= distance_m + 1 + 1e-9))
    assert np.all(fp.b_m[:, 2] < 0) and np.isclose(fp.b_m[:, 1], distance_m + 1.0).any()


def test_literal_next_point_is_too_close_for_eq14():
    scan = hdl32_side_scan([Hole.ahead(8.0, 1.0, 1.0, 0.8)])
    assert len(extract_hdl32_pairs(scan, Hdl32FeatureConfig(c_min_separation_m=0.0))) == 0


def test_flat_plane_with_noise_yields_at_most_two_pairs():
    for seed in range(3):
        scan = hdl32_side_scan(noise_sigma_m=0.02, rng=np.random.default_rng(seed))
        assert len(extract_hdl32_pairs(scan, CFG)) <= 2


def test_empty_scan():
    empty = StructuredScan(
        "hdl32_left", np.empty((32, 0)), np.empty(0), np.linspace(-0.5, 0.2, 32), translation_m=[0, 0, 2]
    )
    assert len(extract_hdl32_pairs(empty, CFG)) == 0


def test_config_validation():
    with pytest.raises(ConfigError, match="jump_threshold_m"):
        Hdl32FeatureConfig(jump_threshold_m=0)
    with pytest.raises(ConfigError, match="c_min_separation_m"):
        Hdl32FeatureConfig(c_min_separation_m=-1)
    assert CFG.pair_test.gamma1 == 5.0 and CFG.pair_test.gamma2 == 0.4


def test_density_threshold_is_the_papers_up_to_12_m_then_falls_with_range_squared():
    cfg = Hdl32FeatureConfig()
    pts = np.array([[0.0, 6.0, 0.0], [0.0, 12.0, 0.0], [0.0, 16.97, 0.0], [0.0, 40.0, 0.0]])
    thr = density_threshold(pts, np.zeros(3), cfg)
    np.testing.assert_allclose(thr, [4.0, 4.0, 2.0, 1.5], atol=0.01)
    paper = Hdl32FeatureConfig(density_full_range_m=float("inf"))
    np.testing.assert_allclose(density_threshold(pts, np.zeros(3), paper), 4.0)


def test_side_sensor_finds_a_pit_at_14_m_only_with_the_range_density():
    # at 14 m the back wall of a 1 m pit holds 3-4 returns within 0.15 m: the paper's D_th32 = 4
    # (strictly more) removes every jump, the range-scaled threshold (2.9) keeps them
    scan = hdl32_side_scan([Hole.ahead(14.0, 1.0, 1.0, 0.8)], side="left")
    pairs = extract_hdl32_pairs(scan, Hdl32FeatureConfig())
    assert len(pairs) >= 2 and np.all((pairs.b_m[:, 1] > 14.0) & (pairs.b_m[:, 1] < 15.2))
    assert len(extract_hdl32_pairs(scan, Hdl32FeatureConfig(density_full_range_m=float("inf")))) == 0
