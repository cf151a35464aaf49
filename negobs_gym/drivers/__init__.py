"""Deterministic scripted drivers sharing one protocol: ``reset(seed)``, ``act(obs, info)``."""

from negobs_gym.drivers.base import Driver
from negobs_gym.drivers.constant_speed import ConstantSpeedConfig, ConstantSpeedDriver
from negobs_gym.drivers.pure_pursuit import PurePursuitConfig, PurePursuitDriver
from negobs_gym.drivers.reckless import RecklessConfig, RecklessDriver

__all__ = [
    "ConstantSpeedConfig",
    "ConstantSpeedDriver",
    "Driver",
    "PurePursuitConfig",
    "PurePursuitDriver",
    "RecklessConfig",
    "RecklessDriver",
]
