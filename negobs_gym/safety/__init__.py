"""Eq. 18 braking safety filter and the hazard protocol any env can implement to use it."""

from negobs_gym.safety.braking import BrakingConfig, braking_distance_m, max_safe_speed_mps
from negobs_gym.safety.corridor import Corridor, hazard_distance_m
from negobs_gym.safety.decision import SafetyDecision
from negobs_gym.safety.filter import BrakingSafetyFilter, SafetyFilterConfig, filter_config
from negobs_gym.safety.protocol import DecisionSink, HazardSource, HazardState

__all__ = [
    "BrakingConfig",
    "BrakingSafetyFilter",
    "Corridor",
    "DecisionSink",
    "HazardSource",
    "HazardState",
    "SafetyDecision",
    "SafetyFilterConfig",
    "braking_distance_m",
    "filter_config",
    "hazard_distance_m",
    "max_safe_speed_mps",
]
