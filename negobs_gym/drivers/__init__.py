"""Drivers sharing one protocol: ``reset(seed)``, ``act(obs, info)``.

The scripted drivers all but :class:`TrackPlannerDriver` read only the env's info and
observation; it reads the course's ground truth (an expert for demonstrations, not a sensor-driven
baseline). :class:`GridPlannerDriver` plans the same way around what the ``grid`` observation shows.
:class:`ModelDriver` drives with a saved stable-baselines3 model or a shipped one
(:mod:`negobs_gym.drivers.zoo`, the files in ``negobs_gym/drivers/trained``).
"""

from negobs_gym.drivers.base import Driver
from negobs_gym.drivers.by_name import DRIVER_NAMES, driver_config, make_driver
from negobs_gym.drivers.constant_speed import ConstantSpeedConfig, ConstantSpeedDriver
from negobs_gym.drivers.creeping import CreepingConfig, CreepingDriver
from negobs_gym.drivers.grid_planner import GridPlannerConfig, GridPlannerDriver
from negobs_gym.drivers.model import ModelDriver, PolicyDriver, match_observation
from negobs_gym.drivers.pure_pursuit import PurePursuitConfig, PurePursuitDriver
from negobs_gym.drivers.reckless import RecklessConfig, RecklessDriver
from negobs_gym.drivers.track_planner import TrackPlannerConfig, TrackPlannerDriver

__all__ = [
    "DRIVER_NAMES",
    "ConstantSpeedConfig",
    "ConstantSpeedDriver",
    "CreepingConfig",
    "CreepingDriver",
    "Driver",
    "GridPlannerConfig",
    "GridPlannerDriver",
    "ModelDriver",
    "PolicyDriver",
    "PurePursuitConfig",
    "PurePursuitDriver",
    "RecklessConfig",
    "RecklessDriver",
    "TrackPlannerConfig",
    "TrackPlannerDriver",
    "driver_config",
    "make_driver",
    "match_observation",
]
