"""Eq. 18's check of one steering command, and the search for the nearest command that passes it.

The filter (:class:`~negobs_gym.safety.BrakingSafetyFilter`) decides with these, and a driver can
ask the same question before it proposes an action: does the corridor of this steering leave
room to stop, with some travel to spare?
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.safety.braking import braking_distance_m
from negobs_gym.safety.config import SafetyFilterConfig
from negobs_gym.safety.corridor import Corridor
from negobs_gym.safety.protocol import HazardState

__all__ = ["SteeringCheck", "check_steering", "nearest_clear_steering", "passes_eq18"]


@dataclass(frozen=True)
class SteeringCheck:
    """One steering command's corridor and its nearest hazard.

    Attributes:
        steer: The command (action units, +1 = full left).
        corridor: The corridor its arc sweeps.
        hazard_distance_m: Arc length to the nearest hazard in it (inf: clear) [m].
        channel: ``"negative"`` or ``"positive"``: the grid channel of that hazard (None: clear).
    """

    steer: float
    corridor: Corridor
    hazard_distance_m: float
    channel: str | None


def check_steering(state: HazardState, config: SafetyFilterConfig, steer: float) -> SteeringCheck:
    """The corridor of steering command ``steer`` (the body widened by ``config.margin_m``) and the
    arc length to its nearest negative-obstacle point (with ``stop_for_positive``, the nearer of
    the negative and positive points)."""
    corridor = Corridor(
        steer_rad=steer * state.max_steer_rad,
        wheelbase_m=state.wheelbase_m,
        half_width_m=0.5 * (state.vehicle_width_m + config.margin_m),
        front_length_m=state.front_length_m,
    )
    d = corridor.hazard_distance_m(state.negative_obstacles_xy_m)
    channel = "negative" if np.isfinite(d) else None
    if config.stop_for_positive:
        d_positive = corridor.hazard_distance_m(state.positive_obstacles_xy_m)
        if d_positive < d:
            d, channel = d_positive, "positive"
    return SteeringCheck(float(steer), corridor, float(d), channel)


def passes_eq18(
    state: HazardState,
    config: SafetyFilterConfig,
    hazard_distance_m: float,
    longitudinal: float,
    *,
    holding: bool = False,
    lead_s: float = 0.0,
) -> bool:
    """Eq. 18 after one control period: ``d - travelled >= R(v')`` for the speed v' that
    ``longitudinal`` leaves, plus ``config.release_margin_m`` while ``holding`` (the last decision
    was a veto) and ``lead_s`` of travel at v' to spare."""
    v_next = state.predicted_speed_mps(longitudinal)
    margin = config.release_margin_m if holding else 0.0
    room = hazard_distance_m - state.travelled_m(v_next)
    return bool(room >= braking_distance_m(v_next, config.braking) + margin + v_next * lead_s)


def nearest_clear_steering(
    state: HazardState,
    config: SafetyFilterConfig,
    steer: float,
    longitudinal: float,
    *,
    search: float,
    lead_s: float,
    holding: bool = False,
) -> SteeringCheck | None:
    """The steering command nearest ``steer``, at most ``search`` away in steps of
    ``config.steer_search_step`` and within full lock, whose corridor passes Eq. 18 with
    ``longitudinal`` and ``lead_s`` to spare (:func:`passes_eq18`); at equal change, the one with
    the longer hazard distance. None: none does. ``steer`` itself is not tried. The commands are
    float32 values, as the env receives them."""
    step = config.steer_search_step
    for k in range(1, math.floor(search / step + 1e-9) + 1):
        passing = []
        for offset in (-k * step, k * step):
            candidate = float(np.float32(steer + offset))
            if abs(candidate) > 1.0:
                continue
            check = check_steering(state, config, candidate)
            d = check.hazard_distance_m
            if passes_eq18(state, config, d, longitudinal, holding=holding, lead_s=lead_s):
                passing.append(check)
        if passing:
            return max(passing, key=lambda found: found.hazard_distance_m)
    return None
