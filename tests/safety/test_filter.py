import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from negobs_gym.drivers import RecklessDriver
from negobs_gym.errors import ActionError, ConfigError, InterfaceError
from negobs_gym.safety import (
    BrakingConfig,
    BrakingSafetyFilter,
    HazardState,
    SafetyFilterConfig,
    braking_distance_m,
)

from .standins import DITCH_Y_M, DT_S, FixedHazardEnv, PointCarDitchEnv

HW = 0.5 * (1.8 + 0.4)


FRONT_M = 3.0  # rear axle to front bumper of the test car


def brute_distance(points, steer_rad, wheelbase, half_width, front_length=0.0, ds=0.01, s_max=80.0):
    """Arc length at which the rear axle's cross line passes a point the swept body covers.

    The body (the rectangle from the rear axle to ``front_length`` ahead, ``half_width`` either
    side) is posed every ``ds`` along the path; a point it covers at some pose is at the arc length
    where its along-track coordinate next crosses zero on the near side of the turn centre, from
    the first pose that covers it on (a point beside the outer rear is covered, if ever, only a
    turn later: its first crossing does not count).
    """
    s = np.arange(0.0, s_max, ds)
    kappa = np.tan(steer_rad) / wheelbase
    if abs(kappa) < 1e-9:
        cx, cy, hx, hy = np.zeros_like(s), s, np.zeros_like(s), np.ones_like(s)
        radius = np.inf
    else:
        th = kappa * s  # heading change, left positive; heading vector (-sin, cos)
        cx = (np.cos(th) - 1.0) / kappa
        cy = np.sin(th) / kappa
        hx, hy = -np.sin(th), np.cos(th)
        radius = 1.0 / abs(kappa)
    best = np.inf
    for p in points:
        rx, ry = p[0] - cx, p[1] - cy
        along = rx * hx + ry * hy
        across = rx * hy - ry * hx
        covered = (along >= 0.0) & (along <= front_length) & (np.abs(across) <= half_width)
        crossing = (np.abs(along) <= 0.7 * ds) & (np.abs(across) < radius)
        if front_length == 0.0:  # the cross-axle segment itself
            covered = crossing & (np.abs(across) <= half_width)
        if np.any(covered):
            after = crossing & (s >= s[np.argmax(covered)] - ds)
            if np.any(after):
                best = min(best, s[np.argmax(after)])
    return best


def make_state(v, points, time_s=0.0, perception_time_s=0.0):
    return HazardState(
        speed_mps=v,
        negative_obstacles_xy_m=points,
        vehicle_width_m=1.8,
        wheelbase_m=2.8,
        front_length_m=FRONT_M,
        max_steer_rad=float(np.deg2rad(35)),
        dt_s=0.1,
        max_accel_mps2=3.0,
        max_brake_decel_mps2=0.65 * 9.81,
        time_s=time_s,
        perception_time_s=perception_time_s,
    )


points_st = st.lists(st.tuples(st.floats(-25, 25), st.floats(0.5, 40)), min_size=0, max_size=6).map(
    lambda p: np.array(p, dtype=float).reshape(-1, 2)
)
# one filter decision: speed, proposed action, detected points, mode
DECISION_CASE = {
    "v": st.floats(0, 12),
    "a0": st.floats(-1, 1),
    "steer": st.floats(-1, 1),
    "pts": points_st,
    "mode": st.sampled_from(["brake", "cap_speed"]),
}


@settings(max_examples=1000, deadline=None)
@given(**DECISION_CASE)
@example(
    v=0.0, a0=0.0, steer=1.0, pts=np.array([[1.1, 1.125]]), mode="brake"
)  # on the side at its entry angle
@example(v=0.0, a0=0.0, steer=0.25, pts=np.array([[1.25, 1.0]]), mode="brake")  # beside the outer rear
def test_never_lets_unsafe_through(v, a0, steer, pts, mode):
    state = make_state(v, pts)
    env = BrakingSafetyFilter(FixedHazardEnv(state), mode=mode)
    action = np.array([a0, steer], dtype=np.float32)
    _, _, _, _, info = env.step(action)
    rec = info["safety"]
    applied = env.unwrapped.received
    assert applied[1] == action[1]
    d_bf = brute_distance(pts, float(action[1]) * state.max_steer_rad, 2.8, HW, FRONT_M)
    v_next = state.predicted_speed_mps(float(applied[0]))
    ok = d_bf + 0.02 - state.travelled_m(v_next) >= float(braking_distance_m(v_next))
    if not rec["vetoed"]:
        assert ok
        assert applied is action  # passes unchanged
    else:
        assert ok or applied[0] == -1.0  # unavoidable: full brake is the best there is
        assert info["cost"] == 1.0
    if np.isinf(d_bf):
        assert not rec["vetoed"] and applied is action


def test_ditch_standin_reckless():
    driver = RecklessDriver()
    for use_filter in (False, True):
        env = PointCarDitchEnv()
        if use_filter:
            env = BrakingSafetyFilter(env)
        obs, info = env.reset(seed=0)
        for _ in range(400):
            obs, _, term, _, info = env.step(driver.act(obs, info))
            if term:
                break
        y, v = obs
        if use_filter:
            assert y < DITCH_Y_M and v == 0.0
            assert DITCH_Y_M - y >= 5.0 - 0.05
        else:
            assert y >= DITCH_Y_M


def test_cap_speed_mode_holds_safe_speed():
    env = BrakingSafetyFilter(PointCarDitchEnv(), mode="cap_speed")
    obs, _ = env.reset(seed=0)
    for _ in range(400):
        obs, _, term, _, _ = env.step(np.array([1.0, 0.0], np.float32))
        assert not term
    assert DITCH_Y_M - obs[0] >= 5.0 - 1e-6


class NoProtocolEnv(gym.Env):
    action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)


def test_missing_protocol():
    with pytest.raises(InterfaceError, match="hazard_state"):
        BrakingSafetyFilter(NoProtocolEnv())


@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf], [0.0], [[0.0, 0.0]]])
def test_bad_actions(bad):
    env = BrakingSafetyFilter(FixedHazardEnv(make_state(1.0, np.zeros((0, 2)))))
    with pytest.raises(ActionError):
        env.step(np.array(bad))


@pytest.mark.parametrize("kw", [{"mu": 0.0}, {"margin_m": -1.0}, {"mode": "swerve"}])
def test_bad_config(kw):
    with pytest.raises(ConfigError):
        BrakingSafetyFilter(FixedHazardEnv(make_state(1.0, np.zeros((0, 2)))), **kw)


def _drive(env, steps=400):
    """Full throttle straight ahead; the per-step info dicts."""
    env.reset(seed=0)
    infos = []
    for _ in range(steps):
        _, _, term, _, info = env.step(np.array([1.0, 0.0], np.float32))
        infos.append(info)
        if term:
            break
    return infos


@pytest.mark.parametrize("timeout_s", [0.2, 0.5])
def test_brakes_when_perception_is_older_than_its_limit(timeout_s):
    """The sensor dies at t = 1 s, 20 m before the ditch: the filter brakes once the data is too old."""
    env = BrakingSafetyFilter(PointCarDitchEnv(sensor_dies_at_s=1.0), perception_timeout_s=timeout_s)
    infos = _drive(env, 60)
    ages = np.array([i["safety"]["perception_age_s"] for i in infos])
    stale = np.array([i["safety"]["perception_stale"] for i in infos])
    vetoed = np.array([i["safety"]["vetoed"] for i in infos])
    applied = np.array([i["safety"]["applied_action"][0] for i in infos])
    np.testing.assert_array_equal(stale, ages > timeout_s)
    assert stale.any() and not stale[0]
    first = int(np.argmax(stale))
    assert 0.9 < first * DT_S < 1.0 + timeout_s + DT_S  # the first stale decision, not earlier
    assert not vetoed[:first].any()  # fresh data, hazard far: full throttle passes
    assert vetoed[first:].all() and np.all(applied[first:] == -1.0)  # from then on: full brake
    assert all(i["cost"] == 1.0 for i in infos[first:])
    y, v = env.unwrapped.y, env.unwrapped.v
    assert v == 0.0 and y < DITCH_Y_M - 10.0  # stopped long before the ditch it no longer sees


def test_fresh_perception_does_not_brake_early():
    """Same drive with a working sensor: no stale decision, the Eq. 18 stop only near the ditch."""
    infos = _drive(BrakingSafetyFilter(PointCarDitchEnv()))
    assert not any(i["safety"]["perception_stale"] for i in infos)
    assert max(i["safety"]["perception_age_s"] for i in infos) == 0.0


@pytest.mark.parametrize("mode", ["brake", "cap_speed"])
def test_missing_perception_brakes(mode):
    state = make_state(5.0, np.zeros((0, 2)), time_s=3.0, perception_time_s=None)
    env = BrakingSafetyFilter(FixedHazardEnv(state), mode=mode)
    _, _, _, _, info = env.step(np.array([0.7, 0.2], np.float32))
    rec = info["safety"]
    assert rec["vetoed"] and rec["perception_stale"] and np.isposinf(rec["perception_age_s"])
    assert np.isposinf(rec["hazard_distance_m"])  # nothing detected, still brakes: fail-safe
    np.testing.assert_array_equal(env.unwrapped.received, np.array([-1.0, 0.2], np.float32))
    assert env.last_decision is not None and env.last_decision.perception_stale


def test_hazard_state_rejects_perception_from_the_future():
    with pytest.raises(ConfigError, match="perception_time_s") as err:
        make_state(1.0, np.zeros((0, 2)), time_s=1.0, perception_time_s=1.5)
    assert err.value.field == "perception_time_s"


def test_config_form_is_used():
    config = SafetyFilterConfig(braking=BrakingConfig(buffer_m=8.0), mode="cap_speed")
    env = BrakingSafetyFilter(PointCarDitchEnv(), config=config)
    assert env.config is config
    infos = _drive(env)
    y = env.unwrapped.y
    assert DITCH_Y_M - y >= 8.0 - 1e-6
    assert any(i["safety"]["vetoed"] for i in infos)


def test_stale_counts_from_the_envs_frame_age() -> None:
    """An env whose frames come every 3 steps (``max_perception_age_s`` 0.2 s): hazards 0.35 s old
    are within the default 0.2 s timeout beyond that age, 0.45 s old are stale; a bad age is refused."""
    for age_s, stale in ((0.35, False), (0.45, True)):
        source = FixedHazardEnv(
            make_state(0.0, np.zeros((0, 2)), time_s=10.0, perception_time_s=10.0 - age_s)
        )
        source.max_perception_age_s = 0.2
        _, rec = BrakingSafetyFilter(source).filter_action(np.array([0.5, 0.0], np.float32))
        assert rec.perception_stale is stale
    for bad in (-0.1, float("nan"), "0.2"):
        source.max_perception_age_s = bad
        with pytest.raises(InterfaceError, match="max_perception_age_s"):
            BrakingSafetyFilter(source)


@settings(max_examples=100, deadline=None)
@given(
    **DECISION_CASE,
    mu=st.floats(0.2, 1.0),
    buffer_m=st.floats(0.0, 10.0),
    reaction_time_s=st.floats(0.0, 1.0),
    margin_m=st.floats(0.0, 1.0),
    age_s=st.floats(0.0, 0.4),
)
def test_keyword_and_config_forms_decide_the_same(
    v, a0, steer, pts, mu, buffer_m, reaction_time_s, margin_m, mode, age_s
):
    state = make_state(v, pts, time_s=10.0, perception_time_s=10.0 - age_s)
    kw = {"mu": mu, "buffer_m": buffer_m, "reaction_time_s": reaction_time_s, "margin_m": margin_m}
    by_kw = BrakingSafetyFilter(FixedHazardEnv(state), mode=mode, **kw)
    config = SafetyFilterConfig(
        braking=BrakingConfig(mu=mu, buffer_m=buffer_m, reaction_time_s=reaction_time_s),
        margin_m=margin_m,
        mode=mode,
    )
    by_config = BrakingSafetyFilter(FixedHazardEnv(state), config=config)
    assert by_kw.config == by_config.config
    action = np.array([a0, steer], np.float32)
    _, rec_kw = by_kw.filter_action(action)
    _, rec_cfg = by_config.filter_action(action)
    assert rec_kw.vetoed == rec_cfg.vetoed
    assert rec_kw.hazard_distance_m == rec_cfg.hazard_distance_m
    np.testing.assert_array_equal(rec_kw.applied_action, rec_cfg.applied_action)


def test_defaults_are_the_papers_and_equal_in_both_forms():
    env = FixedHazardEnv(make_state(1.0, np.zeros((0, 2))))
    b = BrakingSafetyFilter(env).config.braking
    assert (b.mu, b.reaction_time_s, b.buffer_m, b.g_mps2) == (0.65, 0.25, 5.0, 9.81)  # Eq. 18
    assert BrakingSafetyFilter(env).config == BrakingSafetyFilter(env, config=SafetyFilterConfig()).config


def test_config_and_keywords_together_are_an_error():
    env = FixedHazardEnv(make_state(1.0, np.zeros((0, 2))))
    with pytest.raises(ConfigError, match=r"not both.*margin_m") as err:
        BrakingSafetyFilter(env, config=SafetyFilterConfig(), margin_m=1.0)
    assert err.value.field == "config"
    with pytest.raises(ConfigError) as err:
        BrakingSafetyFilter(env, config={"mu": 0.5})
    assert err.value.field == "config"


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"perception_timeout_s": 0.0}, "perception_timeout_s"),
        ({"perception_timeout_s": np.nan}, "perception_timeout_s"),
        ({"margin_m": -1.0}, "margin_m"),
        ({"mode": "swerve"}, "mode"),
        ({"braking": {"mu": 0.5}}, "braking"),
    ],
)
def test_invalid_config_names_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field) as err:
        SafetyFilterConfig(**kwargs)
    assert err.value.field == field
    with pytest.raises(ConfigError) as err:
        BrakingConfig(reaction_time_s=-1.0)
    assert err.value.field == "reaction_time_s"


def _ahead(distance_m: float) -> np.ndarray:
    """Hazard points straight ahead whose corridor distance is ``distance_m`` (probe-calibrated)."""
    probe = BrakingSafetyFilter(FixedHazardEnv(make_state(0.0, np.array([[0.0, 10.0]]))))
    _, decision = probe.filter_action(np.array([0.0, 0.0], np.float32))
    offset = 10.0 - decision.hazard_distance_m
    return np.array([[0.0, distance_m + offset]])


def test_after_a_veto_an_action_needs_the_release_margin_until_one_passes():
    env = FixedHazardEnv(make_state(0.0, _ahead(3.0)))
    f = BrakingSafetyFilter(env)  # release_margin_m = 1.0
    f.reset(seed=0)
    throttle = np.array([1.0, 0.0], np.float32)
    # full throttle from standstill: v' = 0.3 m/s, R(v') = 5.08 m, travelled 0.015 m
    fresh = BrakingSafetyFilter(FixedHazardEnv(make_state(0.0, _ahead(5.6))))
    assert not fresh.filter_action(throttle)[1].vetoed  # 5.6 >= 5.10: passes without a veto before
    f.step(throttle)
    assert f.last_decision.vetoed  # 3 m: vetoed
    env.state = make_state(0.0, _ahead(5.6))
    f.step(throttle)
    assert f.last_decision.vetoed  # 5.6 < 5.10 + 1.0: still held
    env.state = make_state(0.0, _ahead(6.2))
    f.step(throttle)
    assert not f.last_decision.vetoed  # 6.2 >= 6.10: released
    env.state = make_state(0.0, _ahead(5.6))
    f.step(throttle)
    assert not f.last_decision.vetoed  # no veto before: the plain Eq. 18 test again
    env.state = make_state(0.0, _ahead(3.0))
    f.step(throttle)
    env.state = make_state(0.0, _ahead(5.6))
    f.reset(seed=1)
    f.step(throttle)
    assert not f.last_decision.vetoed  # reset clears the hysteresis


def test_release_margin_zero_is_the_stateless_filter_and_negative_is_rejected():
    env = FixedHazardEnv(make_state(0.0, _ahead(3.0)))
    f = BrakingSafetyFilter(env, release_margin_m=0.0)
    throttle = np.array([1.0, 0.0], np.float32)
    f.step(throttle)
    env.state = make_state(0.0, _ahead(5.6))
    f.step(throttle)
    assert not f.last_decision.vetoed
    with pytest.raises(ConfigError, match="release_margin_m"):
        SafetyFilterConfig(release_margin_m=-1.0)


def test_filter_action_alone_does_not_move_the_hysteresis():
    env = FixedHazardEnv(make_state(0.0, _ahead(3.0)))
    f = BrakingSafetyFilter(env)
    throttle = np.array([1.0, 0.0], np.float32)
    assert f.filter_action(throttle)[1].vetoed  # a look at the decision, no step
    env.state = make_state(0.0, _ahead(5.6))
    assert not f.filter_action(throttle)[1].vetoed  # plain Eq. 18 test: nothing was committed


def _with_positive(state: HazardState, points: np.ndarray) -> HazardState:
    return dataclasses.replace(state, positive_obstacles_xy_m=points)


def test_positive_obstacles_are_ignored_unless_stop_for_positive():
    rock_ahead = np.array([[0.0, 6.0]])  # a rock 6 m ahead; R(25 km/h) = 10.5 m
    state = _with_positive(make_state(25 / 3.6, np.zeros((0, 2))), rock_ahead)
    action = np.array([0.5, 0.0], np.float32)
    paper = BrakingSafetyFilter(FixedHazardEnv(state))
    applied, decision = paper.filter_action(action)
    assert not decision.vetoed and applied is action
    assert decision.hazard_distance_m == np.inf and decision.hazard_channel is None

    for guard in (
        BrakingSafetyFilter(FixedHazardEnv(state), stop_for_positive=True),
        BrakingSafetyFilter(FixedHazardEnv(state), config=SafetyFilterConfig(stop_for_positive=True)),
    ):
        applied, decision = guard.filter_action(action)
        assert decision.vetoed and applied[0] == -1.0 and applied[1] == action[1]
        assert decision.hazard_channel == "positive"
        assert decision.hazard_distance_m == pytest.approx(6.0, abs=0.3)
        assert decision.as_dict()["hazard_channel"] == "positive"


def test_the_nearer_channel_decides_and_is_named():
    ditch, rock = np.array([[0.0, 20.0]]), np.array([[0.0, 30.0]])
    guard = BrakingSafetyFilter(
        FixedHazardEnv(_with_positive(make_state(5.0, ditch), rock)), stop_for_positive=True
    )
    _, decision = guard.filter_action(np.array([0.0, 0.0], np.float32))
    assert decision.hazard_channel == "negative" and decision.hazard_distance_m < 21.0
    guard = BrakingSafetyFilter(
        FixedHazardEnv(_with_positive(make_state(5.0, rock), ditch)), stop_for_positive=True
    )
    _, decision = guard.filter_action(np.array([0.0, 0.0], np.float32))
    assert decision.hazard_channel == "positive" and decision.hazard_distance_m < 21.0


def test_a_rock_beside_the_corridor_does_not_stop_the_car():
    beside = np.array([[3.0, 6.0], [-3.0, 6.0]])  # 3 m either side, the corridor is 1.1 m half-wide
    state = _with_positive(make_state(25 / 3.6, np.zeros((0, 2))), beside)
    _, decision = BrakingSafetyFilter(FixedHazardEnv(state), stop_for_positive=True).filter_action(
        np.array([0.5, 0.0], np.float32)
    )
    assert not decision.vetoed and decision.hazard_channel is None


@pytest.mark.parametrize(
    "points", [np.array([[np.nan, 5.0]]), np.array([[0.0, np.inf]]), np.zeros((3, 3)), np.zeros(4)]
)
def test_hazard_state_rejects_bad_positive_points_by_name(points):
    with pytest.raises(ConfigError) as err:
        _with_positive(make_state(1.0, np.zeros((0, 2))), points)
    assert err.value.field == "positive_obstacles_xy_m"


def test_stop_for_positive_must_be_a_bool():
    with pytest.raises(ConfigError) as err:
        SafetyFilterConfig(stop_for_positive="yes")
    assert err.value.field == "stop_for_positive"


def test_filter_config_reads_flags_and_configs():
    from negobs_gym.safety import filter_config

    custom = SafetyFilterConfig(stop_for_positive=True)
    assert filter_config(custom) is custom
    assert filter_config(True) == filter_config(np.True_) == filter_config(1) == SafetyFilterConfig()
    assert filter_config(False) is None and filter_config(np.False_) is None and filter_config(0) is None


@pytest.mark.parametrize("steer", [-0.7, 0.0, 0.4])
def test_the_decision_carries_the_corridor_it_searched(steer):
    pts = np.array([[-3.0, 9.0], [0.2, 14.0], [4.0, 6.0]])
    state = make_state(8.0, pts)
    _, decision = BrakingSafetyFilter(FixedHazardEnv(state)).filter_action(np.array([0.5, steer], np.float32))
    corridor = decision.corridor
    assert corridor.steer_rad == float(np.float32(steer)) * state.max_steer_rad
    assert (corridor.wheelbase_m, corridor.half_width_m, corridor.front_length_m) == (2.8, HW, FRONT_M)
    assert corridor.hazard_distance_m(pts) == decision.hazard_distance_m
    assert decision.as_dict()["corridor"] is corridor  # info["safety"] carries it (frozen)
    with pytest.raises(dataclasses.FrozenInstanceError):
        corridor.steer_rad = 0.0  # type: ignore[misc]
