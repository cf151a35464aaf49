"""Scripted drivers by name: what a scenario's ``run.driver``, ``negobs scenario run --driver`` and
the warm start's demonstrator name."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

from negobs_gym.core.settings import replace_setting
from negobs_gym.drivers.base import Driver
from negobs_gym.drivers.constant_speed import ConstantSpeedConfig, ConstantSpeedDriver
from negobs_gym.drivers.creeping import CreepingConfig, CreepingDriver
from negobs_gym.drivers.grid_planner import GridPlannerConfig, GridPlannerDriver
from negobs_gym.drivers.pure_pursuit import PurePursuitConfig, PurePursuitDriver
from negobs_gym.drivers.reckless import RecklessConfig, RecklessDriver
from negobs_gym.drivers.track_planner import TrackPlannerConfig, TrackPlannerDriver
from negobs_gym.errors import ConfigError
from negobs_gym.safety import SafetyFilterConfig
from negobs_gym.sim.types import Terrain
from negobs_gym.spec.observation import ObservationConfig

__all__ = ["DRIVER_NAMES", "driver_config", "make_driver"]

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
    settings: Mapping[str, Any] | None = None,
    safety_filter: SafetyFilterConfig | None = None,
    control_period_s: float = 0.1,
) -> Driver:
    """The scripted driver ``name`` for one course.

    ``target_speed_mps`` replaces the driver's default cruise speed (None: keep it). Pure pursuit
    follows the centre line shifted by ``lane_offset_m`` (+ right), sampled at the track's own
    stations; the track planner passes the terrain's ground-truth obstacles on the track, with
    ``planner_sight_m`` > 0 only those within that distance ahead (``TrackPlannerConfig.sight_m``),
    with ``planner_horizon_m`` > 0 planning again at every step that far ahead
    (``TrackPlannerConfig.plan_horizon_m``). The grid planner plans on the env's ``grid``
    observation instead, laid out as ``observation`` says (the scenario's ``[observation]``).
    ``settings`` (a scenario's ``run.driver_settings``) then changes fields of the driver's
    config, nested as the config nests them: ``{"planner": {"bend_steps": 1}}`` for the grid
    planner's :class:`GridPlannerConfig`, ``{"lookahead_m": 3.0}`` for pure pursuit's. The grid
    planner's ``filter_lead_s`` keeps to the Eq. 18 of ``safety_filter`` (the scenario's
    ``[filter]``; default :class:`SafetyFilterConfig`) at ``control_period_s``.

    Raises:
        ConfigError: unknown ``name`` (field ``driver``), the grid planner without
            ``observation`` (field ``observation``), or a setting the driver's config does not
            have or refuses (field ``driver_settings``, the message names its path).
    """
    config = driver_config(
        name,
        target_speed_mps=target_speed_mps,
        planner_sight_m=planner_sight_m,
        planner_horizon_m=planner_horizon_m,
        settings=settings,
    )
    if name == "reckless":
        return RecklessDriver(config)
    if name == "constant_speed":
        return ConstantSpeedDriver(config)
    if name == "creeping":
        return CreepingDriver(config)
    if name == "pure_pursuit":
        track = terrain.track
        route = track.pose_at(track.stations_m, lane_offset_m)[0] if lane_offset_m else track.centreline_xy_m
        return PurePursuitDriver(route, config)
    if name == "track_planner":
        return TrackPlannerDriver(terrain, config)
    if observation is None:
        raise ConfigError(
            "observation", "the grid planner needs the grid's layout (the scenario's [observation])"
        )
    return GridPlannerDriver(
        terrain, observation, config, safety_filter=safety_filter, control_period_s=control_period_s
    )


def driver_config(
    name: str,
    *,
    target_speed_mps: float | None = None,
    planner_sight_m: float = 0.0,
    planner_horizon_m: float = 0.0,
    settings: Mapping[str, Any] | None = None,
) -> Any:
    """The config :func:`make_driver` builds driver ``name`` with, from the same arguments; it needs
    no course, so a caller can check ``settings`` before any episode runs.

    Raises:
        ConfigError: unknown ``name`` (field ``driver``) or a setting the driver's config does not
            have or refuses (field ``driver_settings``, the message names its path).
    """
    speed = {} if target_speed_mps is None else {"target_speed_mps": target_speed_mps}
    if name == "reckless":
        return _configured(RecklessConfig(**speed), settings)
    if name == "constant_speed":
        return _configured(ConstantSpeedConfig(**speed), settings)
    if name == "creeping":
        return _configured(CreepingConfig(**speed), settings)
    if name == "pure_pursuit":
        return _configured(PurePursuitConfig(**speed), settings)
    if name == "track_planner":
        config = TrackPlannerConfig(
            sight_m=planner_sight_m, plan_horizon_m=planner_horizon_m, pursuit=PurePursuitConfig(**speed)
        )
        return _configured(config, settings)
    if name == "grid_planner":
        config = GridPlannerConfig()
        planner = dataclasses.replace(config.planner, pursuit=PurePursuitConfig(**speed))
        return _configured(dataclasses.replace(config, planner=planner), settings)
    raise ConfigError("driver", f"unknown driver {name!r}; one of {list(DRIVER_NAMES)}")


Config = TypeVar("Config")


def _configured(config: Config, settings: Mapping[str, Any] | None) -> Config:
    """``config`` with each leaf of the nested ``settings`` set (:func:`replace_setting`)."""

    def leaves(table: Mapping[str, Any], keys: tuple[str, ...]) -> list[tuple[tuple[str, ...], Any]]:
        found = []
        for key, value in table.items():
            if isinstance(value, Mapping):
                found += leaves(value, (*keys, str(key)))
            else:
                found.append(((*keys, str(key)), value))
        return found

    if settings is not None and not isinstance(settings, Mapping):
        raise ConfigError("driver_settings", f"must be a table of the driver's settings, got {settings!r}")
    for keys, value in leaves(settings or {}, ()):
        try:
            config = replace_setting(config, keys, value)
        except ConfigError as exc:
            raise ConfigError("driver_settings", exc.message) from None
    return config
