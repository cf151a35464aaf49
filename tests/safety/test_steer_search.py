"""The filter's steering search: ahead of Eq. 18's boundary, the nearest steering that passes with
the steering lead to spare; at the boundary, paper N's veto."""

import numpy as np
import pytest
from hypothesis import given, settings

from negobs_gym.errors import ConfigError
from negobs_gym.safety import BrakingSafetyFilter, SafetyFilterConfig, braking_distance_m

from .standins import FixedHazardEnv
from .test_filter import DECISION_CASE, FRONT_M, HW, brute_distance, make_state

LEAD_S = SafetyFilterConfig().steer_lead_s


def pit_left(y_m: float) -> np.ndarray:
    """A small pit y_m ahead of the rear axle, left of the axis (inside the straight corridor)."""
    return np.array([[-0.9, y_m], [-0.7, y_m], [-0.5, y_m]])


def passes(state, pts, action, lead_s=0.0) -> bool:
    """Eq. 18 with ``lead_s`` of travel to spare, along the footprint posed every 1 cm (1 cm slack)."""
    d = brute_distance(pts, float(action[1]) * state.max_steer_rad, 2.8, HW, FRONT_M)
    v_next = state.predicted_speed_mps(float(action[0]))
    return d + 0.02 - state.travelled_m(v_next) >= float(braking_distance_m(v_next)) + v_next * lead_s


@settings(max_examples=400, deadline=None)
@given(**DECISION_CASE)
def test_a_steered_action_had_passed_and_passes_with_the_lead(v, a0, steer, pts, mode):
    state = make_state(v, pts)
    env = BrakingSafetyFilter(FixedHazardEnv(state), mode=mode, steer_search=0.3)
    action = np.array([a0, steer], dtype=np.float32)
    _, _, _, _, info = env.step(action)
    applied, rec = env.unwrapped.received, info["safety"]
    if rec["steered"]:
        assert rec["reason"] == "steered" and not rec["vetoed"]
        assert applied[0] == action[0] and 0 < abs(applied[1] - action[1]) <= 0.3 + 1e-6
        assert passes(state, pts, action)  # the search never replaces a veto
        assert passes(state, pts, applied, LEAD_S)
    elif not rec["vetoed"]:
        assert passes(state, pts, action) and applied is action
    else:
        assert applied[1] == action[1]  # a veto brakes on the proposed steering


def test_it_steers_off_a_pit_ahead_of_the_braking_boundary():
    state = make_state(4.0, pit_left(10.0))
    action = np.array([0.3, 0.0], np.float32)
    applied, decision = BrakingSafetyFilter(FixedHazardEnv(state)).filter_action(action)
    assert not decision.vetoed and applied is action  # paper N's filter lets it drive on
    assert not passes(state, pit_left(10.0), action, LEAD_S)  # but with a lead the pit is near

    shield = BrakingSafetyFilter(FixedHazardEnv(state), steer_search=0.5)
    applied, decision = shield.filter_action(action)
    assert decision.steered and not decision.vetoed and decision.reason == "steered"
    assert applied[0] == action[0] and applied[1] < 0  # right, away from the pit on the left
    assert decision.corridor.steer_rad == pytest.approx(float(applied[1]) * state.max_steer_rad)
    assert passes(state, pit_left(10.0), applied, LEAD_S)
    # the smallest change that passes with the lead: one step less does not
    smaller = np.array([0.3, float(applied[1]) + SafetyFilterConfig().steer_search_step], np.float32)
    assert not passes(state, pit_left(10.0), smaller, LEAD_S)


def test_it_never_steers_in_place_of_a_veto():
    """A pit inside the stopping distance: a steering a little to the right would clear it on
    the kinematic arc, but the car's yaw rate takes 0.1-0.7 s to build, so the filter brakes."""
    state = make_state(4.0, pit_left(6.0))
    action = np.array([0.3, 0.0], np.float32)
    assert passes(state, pit_left(6.0), np.array([0.3, -0.3], np.float32))  # the arc would clear
    shield = BrakingSafetyFilter(FixedHazardEnv(state), steer_search=0.5)
    applied, decision = shield.filter_action(action)
    assert decision.vetoed and not decision.steered and decision.reason == "hazard"
    assert applied[0] == -1.0 and applied[1] == action[1]


def test_without_a_passing_steering_it_lets_a_safe_action_through():
    wall = np.array([[x, 10.0] for x in np.arange(-12.0, 12.01, 0.2)])  # a ditch across the path
    state = make_state(4.0, wall)
    action = np.array([0.3, 0.1], np.float32)
    assert passes(state, wall, action) and not passes(state, wall, action, LEAD_S)
    shield = BrakingSafetyFilter(FixedHazardEnv(state), steer_search=0.3)
    applied, decision = shield.filter_action(action)
    assert not decision.vetoed and not decision.steered and decision.reason is None
    assert applied is action


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"steer_search": -0.1}, "steer_search"),
        ({"steer_search": float("nan")}, "steer_search"),
        ({"steer_search": 3.0}, "steer_search"),
        ({"steer_search_step": 0.0}, "steer_search_step"),
        ({"steer_lead_s": 0.0}, "steer_lead_s"),
        ({"steer_lead_s": float("inf")}, "steer_lead_s"),
    ],
)
def test_bad_search_settings_name_the_field(kwargs, field):
    with pytest.raises(ConfigError) as err:
        SafetyFilterConfig(**kwargs)
    assert err.value.field == field
