"""Scripted drivers by name: what a scenario's ``run.driver``, ``negobs scenario run --driver`` and
the warm start's demonstrator name."""

from __future__ import annotations

import dataclasses

from negobs_gym.drivers.base import Driver
from negobs_gym.drivers.constant_speed import ConstantSpeedConfig, ConstantSpeedDriver
from negobs_gym.drivers.creeping import CreepingConfig, CreepingDriver
from negobs_gym.drivers.grid_planner import GridPlannerConfig, GridPlannerDriver
from negobs_gym.drivers.pure_pursuit import PurePursuitConfig, PurePursuitDriver
from negobs_gym.drivers.reckless import RecklessConfig, RecklessDriver
from negobs_gym.drivers.track_planner import TrackPlannerConfig, TrackPlannerDriver
from negobs_gym.errors import ConfigError
from negobs_gym.sim.types import Terrain
from negobs_gym.spec.observation import ObservationConfig

__all__ = ["DRIVER_NAMES", "make_driver"]

#: Names :func:`make_driver` knows.
DRIVER_NAMES: tuple[str, ...] = (
    "reckless",
    "constant_speed",
    "pure_pursuit",
    "track_planner",
    "creeping",
    "grid_planner",
)


def make_driver(
    name: str,
    terrain: Terrain,
    *,
    target_speed_mps: float | None = None,
    lane_offset_m: float = 0.0,
    planner_sight_m: float = 0.0,
    planner_horizon_m: float = 0.0,
    observation: ObservationConfig | None = None,
) -> Driver:
    """The scripted driver ``name`` for one course.

    ``target_speed_mps`` replaces the driver's default cruise speed (None: keep it). Pure pursuit
    follows the centre line shifted by ``lane_offset_m`` (+ right), sampled at the track's own
    stations; the track planner passes the terrain's ground-truth obstacles on the track, with
    ``planner_sight_m`` > 0 only those within that distance ahead (``TrackPlannerConfig.sight_m``),
    with ``planner_horizon_m`` > 0 planning again at every step that far ahead
    (``TrackPlannerConfig.plan_horizon_m``). The grid planner plans on the env's ``grid``
    observation instead, laid out as ``observation`` says (the scenario's ``[observation]``).

    Raises:
        ConfigError: unknown ``name`` (field ``driver``), or the grid planner without
            ``observation`` (field ``observation``).
    """
    speed = {} if target_speed_mps is None else {"target_speed_mps": target_speed_mps}
    if name == "reckless":
        return RecklessDriver(RecklessConfig(**speed))
    if name == "constant_speed":
        return ConstantSpeedDriver(ConstantSpeedConfig(**speed))
    if name == "creeping":
        return CreepingDriver(CreepingConfig(**speed))
    if name == "pure_pursuit":
        track = terrain.track
        route = track.pose_at(track.stations_m, lane_offset_m)[0] if lane_offset_m else track.centreline_xy_m
        return PurePursuitDriver(route, PurePursuitConfig(**speed))
    if name == "track_planner":
        return TrackPlannerDriver(
            terrain,
            TrackPlannerConfig(
                sight_m=planner_sight_m, plan_horizon_m=planner_horizon_m, pursuit=PurePursuitConfig(**speed)
            ),
        )
    if name == "grid_planner":
        if observation is None:
            raise ConfigError(
                "observation", "the grid planner needs the grid's layout (the scenario's [observation])"
            )
        config = GridPlannerConfig()
        planner = dataclasses.replace(config.planner, pursuit=PurePursuitConfig(**speed))
        return GridPlannerDriver(terrain, observation, dataclasses.replace(config, planner=planner))
    raise ConfigError("driver", f"unknown driver {name!r}; one of {list(DRIVER_NAMES)}")
