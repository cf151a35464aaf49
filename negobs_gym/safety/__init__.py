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
    "braking_distance_m",
    "corridor_arcs_m",
    "filter_config",
    "hazard_distance_m",
    "max_safe_speed_mps",
    "observed_clear_distance",
]
