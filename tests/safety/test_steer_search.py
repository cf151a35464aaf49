"""The filter's steering search: the nearest steering whose corridor passes Eq. 18, else a veto."""

import numpy as np
import pytest
from hypothesis import given, settings

from negobs_gym.errors import ConfigError
from negobs_gym.safety import BrakingSafetyFilter, SafetyFilterConfig, braking_distance_m

from .standins import FixedHazardEnv
from .test_filter import DECISION_CASE, FRONT_M, HW, brute_distance, make_state

PIT_AHEAD = np.array([[-0.9, 6.0], [-0.7, 6.0], [-0.5, 6.0]])  # 6 m ahead, left of the axis


@settings(max_examples=400, deadline=None)
@given(**DECISION_CASE)
def test_a_steered_action_is_safe_and_within_the_search(v, a0, steer, pts, mode):
    state = make_state(v, pts)
    env = BrakingSafetyFilter(FixedHazardEnv(state), mode=mode, steer_search=0.3)
    action = np.array([a0, steer], dtype=np.float32)
    _, _, _, _, info = env.step(action)
    applied, rec = env.unwrapped.received, info["safety"]
    steer_applied = float(applied[1]) * state.max_steer_rad
    d_bf = brute_distance(pts, steer_applied, 2.8, HW, FRONT_M)
    v_next = state.predicted_speed_mps(float(applied[0]))
    ok = d_bf + 0.02 - state.travelled_m(v_next) >= float(braking_distance_m(v_next))
    if rec["steered"]:
        assert rec["reason"] == "steered" and not rec["vetoed"]
        assert applied[0] == action[0] and 0 < abs(applied[1] - action[1]) <= 0.3 + 1e-6
        assert ok
    elif not rec["vetoed"]:
        assert ok and applied is action
    else:
        assert applied[1] == action[1]


def test_it_steers_away_from_a_pit_the_straight_corridor_meets_instead_of_braking():
    state = make_state(4.0, PIT_AHEAD)
    action = np.array([0.3, 0.0], np.float32)
    paper = BrakingSafetyFilter(FixedHazardEnv(state))
    applied, decision = paper.filter_action(action)
    assert decision.vetoed and applied[0] == -1.0  # steer_search 0: paper N's filter brakes

    shield = BrakingSafetyFilter(FixedHazardEnv(state), steer_search=0.5)
    applied, decision = shield.filter_action(action)
    assert decision.steered and not decision.vetoed and decision.reason == "steered"
    assert applied[0] == action[0] and applied[1] < 0  # right, away from the pit on the left
    assert decision.corridor.steer_rad == pytest.approx(float(applied[1]) * state.max_steer_rad)
    assert not np.isfinite(decision.hazard_distance_m) or decision.hazard_distance_m > 6.0
    # the smallest change that passes: one step less does not
    smaller = float(applied[1]) + SafetyFilterConfig().steer_search_step
    _, check = BrakingSafetyFilter(FixedHazardEnv(state)).filter_action(np.array([0.3, smaller], np.float32))
    assert check.vetoed


def test_it_brakes_when_no_steering_within_the_search_passes():
    wall = np.array([[x, 5.0] for x in np.arange(-6.0, 6.01, 0.2)])  # a ditch across the path
    shield = BrakingSafetyFilter(FixedHazardEnv(make_state(4.0, wall)), steer_search=0.5)
    applied, decision = shield.filter_action(np.array([0.3, 0.1], np.float32))
    assert decision.vetoed and not decision.steered and decision.reason == "hazard"
    assert applied[0] == -1.0 and applied[1] == np.float32(0.1)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"steer_search": -0.1}, "steer_search"),
        ({"steer_search": float("nan")}, "steer_search"),
        ({"steer_search": 3.0}, "steer_search"),
        ({"steer_search_step": 0.0}, "steer_search_step"),
    ],
)
def test_bad_search_settings_name_the_field(kwargs, field):
    with pytest.raises(ConfigError) as err:
        SafetyFilterConfig(**kwargs)
    assert err.value.field == field
