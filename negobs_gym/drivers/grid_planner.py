"""A perception-driven planner: the track planner's lattice over the obstacles the grid shows.

:class:`~negobs_gym.drivers.track_planner.TrackPlannerDriver` reads the terrain's ground truth.
:class:`GridPlannerDriver` knows only what a policy knows: the env's ``grid`` observation (its
``negative`` and ``positive`` channels, from the detectors, the PEM or the oracle) and the route
(the track's centre line, as the route points in the state). At every step it turns each
connected blob of obstacle cells into a band in track coordinates, plans
(:func:`~negobs_gym.drivers.track_planner.planned_lateral_m`) from where the car is, and pursues
the path. Its action is a function of the observations and the car's place on the route, so it
is a perception-driven baseline for the policies: what an agent that sees only the grid can reach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage

from negobs_gym.core.geometry import vehicle_to_world_xy
from negobs_gym.core.grid import GridSpec, carry_layer
from negobs_gym.core.pose import Pose
from negobs_gym.drivers.pure_pursuit import PurePursuitDriver
from negobs_gym.drivers.track_planner import ObstacleBands, TrackPlannerConfig, planned_lateral_m, track_state
from negobs_gym.errors import ActionError, require
from negobs_gym.safety import BrakingConfig, HazardState, SafetyFilterConfig
from negobs_gym.safety.steering import check_steering, nearest_clear_steering, passes_eq18
from negobs_gym.sim.terrain import track_coordinates
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import VehicleConfig
from negobs_gym.spec.observation import ObservationConfig

__all__ = ["GridPlannerConfig", "GridPlannerDriver", "grid_bands", "observed_cells"]

#: 8-connectivity: a diagonal streak of cells is one blob.
_CONNECTIVITY = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True, kw_only=True)
class GridPlannerConfig:
    """The lattice planner's car, clearances and horizon, how blobs become bands, and the memory
    (papers silent; the defaults are the ones measured best on OffroadNav-v2:
    docs/notebook/training_studies.md, "A planner on the grid").

    ``planner.plan_horizon_m`` must be > 0: the path is planned again at every step. The
    planner's ``wheel_clearance_m`` is 0 here: the detector's pit outlines are up to a cell wider
    than the pits, and OffroadNav-v2's gaps leave the 2 m car 0.1-0.5 m of slack, so the ground-truth
    planner's 0.4 m would close them (4/10 goals at 0.1 m, 8/10 at 0). Behind the filter its best
    configuration also sets ``planner.bend_steps = 1`` and ``filter_lead_s = 1.0`` (docs/training.md,
    "Keeping to the filter's arcs"); both stay 0 here so that the figures measured at the
    defaults stand.
    """

    planner: TrackPlannerConfig = field(
        default_factory=lambda: TrackPlannerConfig(plan_horizon_m=20.0, wheel_clearance_m=0.0)
    )
    # a blob's band reaches this far beyond its outermost cells' centres [m]
    pad_m: float = 0.0
    # a positive blob whose cells' centres span more than this, along or across the track, is a
    # rise in the ground (the winding course's mounds are 4 x 3 m; a rock or box, at most 1 x 1 m,
    # spans two cells' centres at most), driven over at TrackPlannerConfig.mound_cost [m]
    mound_span_m: float = 2.0
    # a body blob's band reaches this far beyond its farthest cell along the track: paper T's LUX
    # returns a rock's or box's near face only, and they are up to 1 m long [m]
    body_depth_m: float = 0.0
    # > 0: also plan around the obstacle cells of the last N grids (N steps at the env's control
    # rate; 30 = 3 s at 10 Hz), moved into the car's frame by its motion since: a hazard memory,
    # since paper T's LUX loses a rock within ~4 m and paper N's rings leave a pit's rim up close
    memory_steps: int = 30
    # > 0: keep the steering to arcs the braking filter passes. When pure pursuit's steering
    # fails Eq. 18 on the grid's negative cells (the memory's included) with this much travel at
    # v' to spare, it takes the nearest steering that passes with it (none: it keeps its own, and
    # the filter decides). The filter checks the arc of a constant steering, so a swerve's full
    # lock meets the pit it swerves round; the filter then brakes, and the car stands beside the
    # pit (docs/notebook/training_studies.md, "The grid planner keeps to the filter's arcs") [s]
    filter_lead_s: float = 0.0

    def __post_init__(self) -> None:
        horizon = self.planner.plan_horizon_m
        require(
            np.isfinite(horizon) and horizon > 0, "planner.plan_horizon_m", f"must be > 0, got {horizon!r}"
        )
        steps = self.memory_steps
        require(isinstance(steps, int) and steps >= 0, "memory_steps", f"must be an int >= 0, got {steps!r}")
        for name in ("pad_m", "mound_span_m", "body_depth_m", "filter_lead_s"):
            value = getattr(self, name)
            require(np.isfinite(value) and value >= 0, name, f"must be finite and >= 0, got {value!r}")


def _blob_extents(mask: np.ndarray, cells: GridSpec, pose: np.ndarray, terrain: Terrain) -> np.ndarray:
    """(N, 4) extents (s0, s1, l0, l1) of the 8-connected blobs of ``mask`` (rows, cols) in track
    coordinates: the stations and lateral offsets of their cells' centres. Centres, not corners:
    an obstacle's edge lies anywhere in its outermost cell, so the centre is the unbiased guess,
    and a band to the corners would close gaps a car fits through."""
    labels, count = ndimage.label(mask, structure=_CONNECTIVITY)
    if count == 0:
        return np.empty((0, 4))
    row, col = np.nonzero(labels)
    world = vehicle_to_world_xy(cells.centres_of(labels > 0), pose[:2], float(pose[5]))
    s, lat = track_coordinates(terrain.track, world)
    blob = labels[row, col] - 1
    bands = np.empty((count, 4))
    bands[:, 0], bands[:, 2] = np.inf, np.inf
    bands[:, 1], bands[:, 3] = -np.inf, -np.inf
    np.minimum.at(bands[:, 0], blob, s)
    np.maximum.at(bands[:, 1], blob, s)
    np.minimum.at(bands[:, 2], blob, lat)
    np.maximum.at(bands[:, 3], blob, lat)
    return bands


def observed_cells(observation: ObservationConfig) -> GridSpec:
    """The grid observation's cells: the scenario's grid pooled by ``downsample``."""
    spec = observation.grid
    return GridSpec(
        cell_m=spec.cell_m * observation.downsample,
        ahead_m=spec.ahead_m,
        back_m=spec.back_m,
        side_m=spec.side_m,
    )


def _checked(grid: Any, observation: ObservationConfig) -> np.ndarray:
    """``grid`` as an array of the observation's (channels, rows, cols), or a clear error. A flat
    grid of that many cells (what :class:`~negobs_gym.policies.PolicyObservation` hands SB3) is
    folded back."""
    array = np.asarray(grid)
    expected = (len(observation.channels), *observed_cells(observation).shape)
    if array.ndim == 1 and array.size == math.prod(expected):
        array = array.reshape(expected)
    if array.shape != expected:
        raise ActionError(f"grid observation: must have shape {expected}, got {array.shape}")
    return array


def grid_bands(
    grid: np.ndarray,
    pose: np.ndarray,
    terrain: Terrain,
    observation: ObservationConfig,
    config: GridPlannerConfig,
) -> ObstacleBands:
    """The obstacle bands of one ``grid`` observation (channels, rows, cols) seen at ``pose``
    (x, y, z, roll, pitch, yaw of the rear axle): ``negative`` blobs as pits (widened for a
    wheel), ``positive`` blobs as bodies (widened for the car's side), or as mounds (driven over
    at a cost) where they span more than ``mound_span_m``; channels the grid lacks give none."""
    return _mask_bands(_checked(grid, observation) > 0, pose, terrain, observation, config)


def _mask_bands(
    mask: np.ndarray,
    pose: np.ndarray,
    terrain: Terrain,
    observation: ObservationConfig,
    config: GridPlannerConfig,
) -> ObstacleBands:
    """:func:`grid_bands` of a boolean (channels, rows, cols) mask of obstacle cells."""
    cells = observed_cells(observation)
    extents = {
        name: _blob_extents(mask[observation.channels.index(name)], cells, pose, terrain)
        if name in observation.channels
        else np.empty((0, 4))
        for name in ("negative", "positive")
    }
    positive = extents["positive"]
    rise = np.maximum(positive[:, 1] - positive[:, 0], positive[:, 3] - positive[:, 2]) > config.mound_span_m
    planner = config.planner
    wheel = planner.half_track_m + planner.wheel_clearance_m + config.pad_m
    body = planner.half_width_m + planner.clearance_m + config.pad_m
    lead = planner.lead_m + config.pad_m

    def widened(extent: np.ndarray, widen_m: float, deepen_m: float = 0.0) -> np.ndarray:
        return extent + np.array([-lead, deepen_m, -widen_m, widen_m])

    return ObstacleBands(
        bodies=widened(positive[~rise], body, config.body_depth_m),
        pits=widened(extents["negative"], wheel),
        mounds=widened(positive[rise], wheel),
        lead_m=planner.lead_m,
    )


class GridPlannerDriver:
    """Pure pursuit along a path planned at every step around the grid's obstacle blobs.

    Reads ``obs["grid"]`` and ``info["pose"]`` (and ``info["speed_mps"]``, as pure pursuit); the
    terrain gives only the track's centre line, the route a navigation system would give. Without
    a finite pose it plans nothing and pure pursuit raises its :class:`ActionError`. With
    ``memory_steps`` > 0 its action depends on the last grids too, as a policy's with stacked
    frames would.
    """

    def __init__(
        self,
        terrain: Terrain,
        observation: ObservationConfig,
        config: GridPlannerConfig | None = None,
        *,
        safety_filter: SafetyFilterConfig | None = None,
        vehicle: VehicleConfig | None = None,
        control_period_s: float = 0.1,
    ) -> None:
        self.config = config or GridPlannerConfig()
        self.terrain = terrain
        self.observation = observation
        #: the filter, car and control period whose Eq. 18 ``filter_lead_s`` keeps to
        self.safety_filter = safety_filter or SafetyFilterConfig()
        self.vehicle = vehicle or VehicleConfig()
        require(
            np.isfinite(control_period_s) and control_period_s > 0,
            "control_period_s",
            f"must be finite and > 0, got {control_period_s!r}",
        )
        self.control_period_s = float(control_period_s)
        self._nothing = ObstacleBands(*(np.empty((0, 4)),) * 3, lead_m=self.config.planner.lead_m)
        self.reset()

    @property
    def path_m(self) -> tuple[np.ndarray, np.ndarray]:
        """The path it follows now: stations and lateral offsets of the rear axle [m]."""
        return self._stations, self._lateral

    @property
    def bands(self) -> ObstacleBands:
        """The obstacle bands it planned the path around: the last grid's and the memory's."""
        return self._bands

    def reset(self, seed: int | None = None) -> None:
        """Start on the centre line with nothing seen."""
        self._memory: list[tuple[Pose, np.ndarray]] = []
        self._bands = self._nothing
        planner = self.config.planner
        self._follow(
            *planned_lateral_m(
                self.terrain, planner, (0.0, 0.0), bands=self._nothing, horizon_m=planner.plan_horizon_m
            )
        )

    def _follow(self, stations: np.ndarray, lateral: np.ndarray) -> None:
        self._stations, self._lateral = stations, lateral
        route_xy_m, _ = self.terrain.track.pose_at(stations, lateral)
        self._pursuit = PurePursuitDriver(route_xy_m, self.config.planner.pursuit)

    def _remembered(self, mask: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """The obstacle ``mask`` with those of the last ``memory_steps`` grids carried into it."""
        steps = self.config.memory_steps
        if steps == 0:
            return mask
        now = Pose(x=pose[0], y=pose[1], yaw=pose[5])
        cells = observed_cells(self.observation)
        merged = mask
        world = cells.world_centres(now)
        for seen_at, earlier in self._memory:
            index = cells.carry_index(seen_at, world)
            merged = merged | np.stack([carry_layer(layer, index) for layer in earlier])
        self._memory = [*self._memory, (now, mask)][-steps:]
        return merged

    def _hazard_state(self, mask: np.ndarray, speed_mps: float) -> HazardState:
        """What the filter would know, read from the obstacle ``mask`` (channels, rows, cols)."""
        cells, channels = observed_cells(self.observation), self.observation.channels

        def points(name: str) -> np.ndarray:
            return cells.centres_of(mask[channels.index(name)]) if name in channels else np.empty((0, 2))

        return HazardState(
            speed_mps=max(0.0, speed_mps),
            negative_obstacles_xy_m=points("negative"),
            positive_obstacles_xy_m=points("positive"),
            **self.vehicle.hazard_geometry(BrakingConfig().g_mps2),  # as the env reports it
            dt_s=self.control_period_s,
            time_s=0.0,
            perception_time_s=0.0,
        )

    def _within_filter(self, action: np.ndarray, mask: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """``action`` with its steering moved, where it must, to the nearest one whose arc passes
        Eq. 18 with ``filter_lead_s`` to spare (:attr:`GridPlannerConfig.filter_lead_s`)."""
        speed = float(info.get("speed_mps", np.nan))
        if not np.isfinite(speed):
            return action
        state = self._hazard_state(mask, speed)
        rules, lead = self.safety_filter, self.config.filter_lead_s
        holding = bool((info.get("safety") or {}).get("vetoed", False))  # the release margin applies
        longitudinal, steer = float(action[0]), float(np.clip(action[1], -1.0, 1.0))
        d = check_steering(state, rules, steer).hazard_distance_m
        if passes_eq18(state, rules, d, longitudinal, holding=holding, lead_s=lead):
            return action
        found = nearest_clear_steering(
            state, rules, steer, longitudinal, search=2.0, lead_s=lead, holding=holding
        )
        if found is None:
            return action
        kept = np.array(action, copy=True)
        kept[1] = found.steer
        return kept

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """Pure pursuit's ``[longitudinal, steering]`` towards the path planned on this step's grid
        (with ``filter_lead_s``, its steering kept to the arcs the filter passes)."""
        pose = np.asarray(info.get("pose", np.full(6, np.nan)), dtype=np.float64)
        mask = None
        if pose.shape == (6,) and np.all(np.isfinite(pose)):
            obstacles = _checked(obs["grid"], self.observation) > 0
            mask = self._remembered(obstacles, pose)
            bands = self._bands = _mask_bands(mask, pose, self.terrain, self.observation, self.config)
            station, lateral, slope = track_state(self.terrain.track, pose)
            planner = self.config.planner
            self._follow(
                *planned_lateral_m(
                    self.terrain,
                    planner,
                    (station, lateral),
                    bands=bands,
                    horizon_m=planner.plan_horizon_m,
                    start_slope=slope,
                )
            )
        action = self._pursuit.act(obs, info)
        if mask is not None and self.config.filter_lead_s > 0:
            action = self._within_filter(action, mask, info)
        return action
