import numpy as np
import pytest

from negobs_gym.core import Pose
from negobs_gym.detector.fusion import (
    FusionConfig,
    PairFusion,
    SensorLikelihood,
    bayes_hit,
    bayes_miss,
)
from negobs_gym.detector.pairs import FeaturePairs
from negobs_gym.errors import ConfigError


def _pair(sensor, a, b):
    a = np.atleast_2d(np.asarray(a, float))
    b = np.atleast_2d(np.asarray(b, float))
    return FeaturePairs(sensor, a, b, np.full_like(a, np.nan))


POSE0 = Pose(x=0.0, y=0.0, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)


def test_eq15_eq16_by_hand():
    lik = SensorLikelihood(p_hit_given_obstacle=0.6, p_hit_given_free=0.2)
    # Eq. 15: 0.6*0.5 / (0.6*0.5 + 0.2*0.5) = 0.75
    assert bayes_hit(np.array([0.5]), lik)[0] == pytest.approx(0.75)
    # Eq. 16: 0.4*0.5 / (0.4*0.5 + 0.8*0.5) = 1/3
    assert bayes_miss(np.array([0.5]), lik)[0] == pytest.approx(1 / 3)


def test_single_sensor_needs_three_frames():
    f = PairFusion()
    fp = {"hdl64": _pair("hdl64", [0, 8, 0], [0, 9, -0.5])}
    r1 = f.update(fp, POSE0)
    r2 = f.update(fp, POSE0)
    assert r1.posterior[0] == pytest.approx(0.75)  # odds 3
    assert r2.posterior[0] == pytest.approx(0.9)  # odds 9 < 19
    assert not r2.confirmed.any()
    r3 = f.update(fp, POSE0)
    assert r3.posterior[0] == pytest.approx(27 / 28)  # odds 27 >= 19
    assert r3.confirmed.all()


def test_three_sensors_confirm_in_one_frame():
    # A pair first seen by one sensor (odds 1 * 3 = 3) that all three sensors detect in the next
    # frame gets odds 3 * 3^3 = 81 >= 19. Three sensors seeing a new pair in the same frame:
    # hdl64 creates it (odds 3); the HDL-32 pairs match the new pair next frame.
    p = [0, 8, 0], [0, 9, -0.5]
    f = PairFusion()
    f.update({"hdl64": _pair("hdl64", *p)}, POSE0)
    r = f.update({s: _pair(s, *p) for s in ("hdl64", "hdl32_left", "hdl32_right")}, POSE0)
    assert len(r) == 1 and r.posterior[0] == pytest.approx(81 / 82) and r.confirmed.all()
    g = PairFusion()
    r = g.update({s: _pair(s, *p) for s in ("hdl64", "hdl32_left", "hdl32_right")}, POSE0)
    assert len(r) == 1 and r.posterior[0] == pytest.approx(27 / 28) and r.confirmed.all()


def test_pose_alignment_keeps_match():
    f = PairFusion()
    f.update({"hdl64": _pair("hdl64", [0, 8, 0], [0, 9, -0.5])}, POSE0)
    moved = Pose(x=0.0, y=1.0, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)
    r = f.update({"hdl64": _pair("hdl64", [0, 7, 0], [0, 8, -0.5])}, moved)
    assert len(r) == 1 and r.posterior[0] == pytest.approx(0.9)


def test_history_bounded_1000_frames():
    rng = np.random.default_rng(0)
    f = PairFusion(FusionConfig(max_pairs=500))
    for k in range(1000):
        a = rng.uniform(-20, 20, (30, 3))
        pose = Pose(x=0.0, y=0.5 * k, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)
        f.update({"hdl64": _pair("hdl64", a, a + 0.5)}, pose)
        assert len(f) <= 500


def test_bad_inputs():
    with pytest.raises(ConfigError):
        FusionConfig(prior=1.5)
    f = PairFusion()
    with pytest.raises(ValueError):
        f.update({"hdl64": _pair("hdl64", [np.nan, 0, 0], [0, 0, 0])}, POSE0)
    assert len(f.update({}, POSE0)) == 0


def test_far_pairs_match_within_a_range_scaled_d_min():
    # a pair moved 0.15 m sideways between two frames: at 8 m beyond d_min = 0.10 m, so the first
    # pair gets a miss (odds 3 -> 1.5); at 18 m within d_min * 18 / 10 = 0.18 m, a second hit
    # (odds 9). Either way the moved pair enters the history (odds 3): it is not within d_min.
    for y, first_odds in ((8.0, 1.5), (18.0, 9.0)):
        f = PairFusion()
        f.update({"hdl32_left": _pair("hdl32_left", [0.0, y, 0], [0.0, y + 1, -0.5])}, POSE0)
        r = f.update({"hdl32_left": _pair("hdl32_left", [0.15, y, 0], [0.15, y + 1, -0.5])}, POSE0)
        np.testing.assert_allclose(r.posterior, [first_odds / (1 + first_odds), 0.75])
    # within d_min the frame pair is the history pair's hit only
    f = PairFusion()
    f.update({"hdl32_left": _pair("hdl32_left", [0.0, 18, 0], [0.0, 19, -0.5])}, POSE0)
    r = f.update({"hdl32_left": _pair("hdl32_left", [0.05, 18, 0], [0.05, 19, -0.5])}, POSE0)
    assert len(r) == 1 and r.posterior[0] == pytest.approx(0.9)
    paper = PairFusion(FusionConfig(match_full_range_m=float("inf")))  # the paper's fixed d_min
    paper.update({"hdl32_left": _pair("hdl32_left", [0.0, 18, 0], [0.0, 19, -0.5])}, POSE0)
    r = paper.update({"hdl32_left": _pair("hdl32_left", [0.15, 18, 0], [0.15, 19, -0.5])}, POSE0)
    np.testing.assert_allclose(r.posterior, [0.6, 0.75])


@pytest.mark.parametrize(
    "field, value", [("match_full_range_m", 0.0), ("max_match_scale", 0.5), ("max_match_scale", np.inf)]
)
def test_bad_range_scale_config(field, value):
    with pytest.raises(ConfigError, match=field):
        FusionConfig(**{field: value})


def test_range_scaled_d_min_applies_to_the_configured_sensors_only():
    # the HDL-64 keeps the paper's fixed d_min at 18 m: the moved pair is a new one, the first a miss
    f = PairFusion()
    f.update({"hdl64": _pair("hdl64", [0.0, 18, 0], [0.0, 19, -0.5])}, POSE0)
    r = f.update({"hdl64": _pair("hdl64", [0.15, 18, 0], [0.15, 19, -0.5])}, POSE0)
    np.testing.assert_allclose(r.posterior, [0.6, 0.75])
    with pytest.raises(ConfigError, match="range_scaled_sensors"):
        FusionConfig(range_scaled_sensors="hdl32_left")


def test_tighten_on_match_moves_a_to_the_farthest_projection_and_keeps_the_posterior():
    # The same rim seen from far (A a ring gap before it) and then from close (A near it):
    # collinear pairs overlap at distance 0, so the close pair is a hit, not a new pair.
    far = _pair("hdl64", [0, 8.0, 0], [0, 10.0, -0.5])
    close = _pair("hdl64", [[0, 9.2, 0], [0, 9.6, 0]], [[0, 10.0, -0.5], [0, 10.0, -0.5]])
    for tighten, a_y in ((False, 8.0), (True, 9.6)):
        f = PairFusion(FusionConfig(tighten_on_match=tighten))
        f.update({"hdl64": far}, POSE0)
        r = f.update({"hdl64": close}, POSE0)
        assert len(r) == 1
        assert r.a_m[0, 1] == pytest.approx(a_y)
        assert r.posterior[0] == pytest.approx(0.9)  # one hit per sensor and frame either way
    # a longer pair never widens the history's
    f = PairFusion(FusionConfig(tighten_on_match=True))
    f.update({"hdl64": _pair("hdl64", [0, 9.6, 0], [0, 10.0, -0.5])}, POSE0)
    r = f.update({"hdl64": far}, POSE0)
    assert len(r) == 1 and r.a_m[0, 1] == pytest.approx(9.6)


def test_tighten_on_match_ignores_pairs_hit_only_by_the_range_scaled_reach():
    # A side HDL-32 pair 16 m out reaches 1.6 x d_min: a pair 0.15 m to the side is a hit but
    # enters the history as a pair of its own, and the history pair keeps its geometry.
    hist = _pair("hdl32_left", [0, 15.0, 0], [0, 17.0, -0.5])
    beside = _pair("hdl32_left", [0.15, 16.0, 0], [0.15, 17.0, -0.5])
    f = PairFusion(FusionConfig(tighten_on_match=True))
    f.update({"hdl32_left": hist}, POSE0)
    r = f.update({"hdl32_left": beside}, POSE0)
    assert len(r) == 2
    assert sorted(r.a_m[:, 1].tolist()) == pytest.approx([15.0, 16.0])


def test_a_partial_frame_misses_only_the_pairs_it_covers():
    """Eq. 16 applies where the frame looked: with ``coverage_xy_m`` (a partial frame) a pair
    outside the box keeps its posterior, one inside is missed, one straddling the edge is kept."""
    f = PairFusion()
    pairs = {
        "hdl64": _pair(
            "hdl64", [[0, 8, 0], [0, 15, 0], [3, 11.5, 0]], [[0, 9, -0.5], [0, 16, -0.5], [3, 12.5, -0.5]]
        )
    }
    for _ in range(3):
        confirmed = f.update(pairs, POSE0)
    assert confirmed.confirmed.all()
    r = f.update({}, POSE0, coverage_xy_m=(-6.4, 6.4, 12.0, 25.6))
    np.testing.assert_allclose(r.posterior, [27 / 28, 13.5 / 14.5, 27 / 28])  # odds 27 x 0.4 / 0.8
    assert r.confirmed.tolist() == [True, False, True]
    whole = PairFusion()
    for _ in range(3):
        whole.update(pairs, POSE0)
    assert not whole.update({}, POSE0).confirmed.any()  # a whole frame misses all three
