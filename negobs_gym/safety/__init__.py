"""Eq. 18 braking safety filter, the observed clear distance and speed governor, and the hazard
protocol any env can implement to use them."""

from negobs_gym.safety.braking import BrakingConfig, braking_distance_m, max_safe_speed_mps
from negobs_gym.safety.config import FILTER_MODES, SafetyFilterConfig, filter_config
from negobs_gym.safety.corridor import Corridor, corridor_arcs_m, hazard_distance_m
from negobs_gym.safety.coverage import ClearDistance, CoverageMemory, observed_clear_distance
from negobs_gym.safety.decision import SafetyDecision
from negobs_gym.safety.filter import BrakingSafetyFilter
from negobs_gym.safety.memory import HazardMemory
from negobs_gym.safety.protocol import DecisionSink, HazardSource, HazardState
from negobs_gym.safety.steering import SteeringCheck, check_steering, nearest_clear_steering, passes_eq18

__all__ = [
    "FILTER_MODES",
    "BrakingConfig",
    "BrakingSafetyFilter",
    "ClearDistance",
    "Corridor",
    "CoverageMemory",
    "DecisionSink",
    "HazardMemory",
    "HazardSource",
    "HazardState",
    "SafetyDecision",
    "SafetyFilterConfig",
    "SteeringCheck",
    "braking_distance_m",
    "check_steering",
    "corridor_arcs_m",
    "filter_config",
    "hazard_distance_m",
    "max_safe_speed_mps",
    "nearest_clear_steering",
    "observed_clear_distance",
    "passes_eq18",
]
