import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from negobs_gym.drivers import RecklessDriver
from negobs_gym.errors import ActionError, ConfigError
from negobs_gym.safety import BrakingSafetyFilter, HazardState, braking_distance_m

from .standins import DITCH_Y_M, FixedHazardEnv, PointCarDitchEnv

HW = 0.5 * (1.8 + 0.4)


def brute_distance(points, steer_rad, wheelbase, half_width, ds=0.01, s_max=80.0):
    """First arc length at which the swept cross-axle segment covers a point (dense sampling)."""
    s = np.arange(0.0, s_max, ds)
    kappa = np.tan(steer_rad) / wheelbase
    if abs(kappa) < 1e-9:
        cx, cy, hx, hy = np.zeros_like(s), s, np.zeros_like(s), np.ones_like(s)
    else:
        th = kappa * s  # heading change, left positive; heading vector (-sin, cos)
        cx = (np.cos(th) - 1.0) / kappa
        cy = np.sin(th) / kappa
        hx, hy = -np.sin(th), np.cos(th)
    best = np.inf
    for p in points:
        rx, ry = p[0] - cx, p[1] - cy
        along = rx * hx + ry * hy
        across = rx * hy - ry * hx
        hit = (np.abs(along) <= 0.7 * ds) & (np.abs(across) <= half_width)
        if np.any(hit):
            best = min(best, s[np.argmax(hit)])
    return best


def make_state(v, points):
    return HazardState(
        speed_mps=v,
        negative_obstacles_xy_m=points,
        vehicle_width_m=1.8,
        wheelbase_m=2.8,
        max_steer_rad=float(np.deg2rad(35)),
        dt_s=0.1,
        max_accel_mps2=3.0,
        max_brake_decel_mps2=0.65 * 9.81,
    )


points_st = st.lists(st.tuples(st.floats(-25, 25), st.floats(0.5, 40)), min_size=0, max_size=6).map(
    lambda p: np.array(p, dtype=float).reshape(-1, 2)
)


@settings(max_examples=1000, deadline=None)
@given(
    v=st.floats(0, 12),
    a0=st.floats(-1, 1),
    steer=st.floats(-1, 1),
    pts=points_st,
    mode=st.sampled_from(["brake", "cap_speed"]),
)
def test_never_lets_unsafe_through(v, a0, steer, pts, mode):
    state = make_state(v, pts)
    env = BrakingSafetyFilter(FixedHazardEnv(state), mode=mode)
    action = np.array([a0, steer], dtype=np.float32)
    _, _, _, _, info = env.step(action)
    rec = info["safety"]
    applied = env.unwrapped.received
    assert applied[1] == action[1]
    d_bf = brute_distance(pts, float(action[1]) * state.max_steer_rad, 2.8, HW)
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
    with pytest.raises(TypeError, match="hazard_state"):
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
