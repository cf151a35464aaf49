"""Eq. 18's check of one steering command and the search for the nearest that passes: the filter's
own functions, which a driver may call before it proposes an action."""

import numpy as np
from hypothesis import given, settings

from negobs_gym.safety import (
    SafetyFilterConfig,
    braking_distance_m,
    check_steering,
    nearest_clear_steering,
    passes_eq18,
)

from .test_filter import DECISION_CASE, FRONT_M, HW, brute_distance, make_state
from .test_steer_search import pit_left

RULES = SafetyFilterConfig()


def room_m(state, pts, action) -> float:
    """d - travelled - R(v') along the footprint posed every 1 cm (1 cm slack), for ``action``."""
    d = brute_distance(pts, float(action[1]) * state.max_steer_rad, 2.8, HW, FRONT_M)
    v_next = state.predicted_speed_mps(float(action[0]))
    return d + 0.02 - state.travelled_m(v_next) - float(braking_distance_m(v_next))


def test_the_check_is_eq18_plus_the_release_margin_while_holding_plus_the_lead() -> None:
    state = make_state(4.0, pit_left(12.0))
    check = check_steering(state, RULES, 0.0)
    assert check.channel == "negative" and 11.9 <= check.hazard_distance_m <= 12.0
    v_next = state.predicted_speed_mps(0.0)
    spare = check.hazard_distance_m - state.travelled_m(v_next) - float(braking_distance_m(v_next))
    assert spare > 0 and passes_eq18(state, RULES, check.hazard_distance_m, 0.0)
    # 12 m - 0.4 m travelled - R(4 m/s) 7.25 m leaves 4.3 m: not the 1 m release margin plus 4 m of lead
    assert passes_eq18(state, RULES, check.hazard_distance_m, 0.0, holding=True)
    assert not passes_eq18(state, RULES, check.hazard_distance_m, 0.0, holding=True, lead_s=1.0)
    assert passes_eq18(state, RULES, check.hazard_distance_m, 0.0, lead_s=spare / v_next - 0.01)
    assert not passes_eq18(state, RULES, check.hazard_distance_m, 0.0, lead_s=spare / v_next + 0.01)
    assert check_steering(make_state(4.0, np.empty((0, 2))), RULES, 0.3).channel is None


@settings(max_examples=200, deadline=None)
@given(**DECISION_CASE)
def test_the_search_finds_the_nearest_steering_that_passes_with_the_lead(v, a0, steer, pts, mode):
    state = make_state(v, pts)
    steer = float(np.float32(steer))
    found = nearest_clear_steering(state, RULES, steer, a0, search=2.0, lead_s=1.0)
    candidates = [float(np.float32(steer + k * RULES.steer_search_step)) for k in range(-40, 41) if k]
    candidates = [s for s in candidates if abs(s) <= 1.0]
    lead = 1.0 * state.predicted_speed_mps(a0)
    clear = [s for s in candidates if room_m(state, pts, (a0, s)) >= lead + 0.02]
    if found is None:  # none passes by more than the footprint's 1 cm grain
        assert not clear
        return
    assert room_m(state, pts, (a0, found.steer)) >= lead - 0.02
    assert found.corridor.steer_rad == found.steer * state.max_steer_rad
    # nothing nearer passes by more than the grain
    assert all(abs(s - steer) >= abs(found.steer - steer) - 1e-6 for s in clear)
