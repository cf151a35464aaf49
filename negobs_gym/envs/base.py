"""The abstract negobs env: physics world + vehicle + events, a grid observation, named rewards.

Scenarios subclass :class:`NegObsEnv` and implement :meth:`NegObsEnv._make_terrain`.
"""

from __future__ import annotations

import abc
import copy
import logging
import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from negobs_gym.core.pose import Pose
from negobs_gym.envs.config import EnvConfig
from negobs_gym.envs.observation import OracleGrid, grid_space, stack_channels, state_space, state_vector
from negobs_gym.envs.perception import DetectorGrid
from negobs_gym.envs.rewards import reward_terms
from negobs_gym.envs.world_cache import CachedWorld, WorldCache, build_world, generator_key
from negobs_gym.errors import ActionError
from negobs_gym.safety.braking import BrakingConfig
from negobs_gym.safety.protocol import HazardState
from negobs_gym.sim.events import EventMonitor, StepEvents
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World, WorldConfig

log = logging.getLogger(__name__)

__all__ = ["NegObsEnv"]


class NegObsEnv(gym.Env, abc.ABC):
    """Drive an off-road vehicle past negative obstacles (abstract base of all negobs envs).

    ## Action Space
    ``Box(-1, 1, (2,), float32)``: ``action[0]`` longitudinal (> 0 throttle, < 0 brake),
    ``action[1]`` steering (+1 = full left). NaN/inf raise :class:`~negobs_gym.errors.ActionError`.
    Control runs at ``config.control_hz`` (10 Hz) with physics sub-steps in between.

    ## Observation Space
    ``Dict(grid, state)``: ``grid`` uint8 (channels, rows, cols) in {0, 1}, vehicle-centred
    (rows along +Y from the rear, cols along +X from the left), channels from
    ``ObservationConfig.channels``; ``state`` float32 (speed, yaw rate, steering angle, goal x, goal
    y in the vehicle frame).

    ## Rewards
    Weighted terms by name in ``info["rewards"]``: progress along the track, negative-obstacle
    entry, collision/rollover, time, goal.

    ## Episode End
    Terminates on entering a negative obstacle, trapped, collision, rollover or reaching the goal;
    truncated by the time limit (``TimeLimit`` wrapper from the registry).

    ## Info
    ``events`` (dict), ``distance_to_negative_ahead_m`` (ground truth, inf if none), ``speed_mps``,
    ``pose`` (float64 array x, y, z, roll, pitch, yaw; ``Pose.from_array`` restores it),
    ``rewards``, ``station_m``, ``goal_reached``.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "human"], "render_fps": 10}  # noqa: RUF012 - gymnasium API

    def __init__(self, config: EnvConfig | None = None, render_mode: str | None = None) -> None:
        self.config = config if config is not None else self.default_config()
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.config.control_hz}
        obs_cfg = self.config.observation
        self.observation_space = spaces.Dict({"grid": grid_space(obs_cfg), "state": state_space(obs_cfg)})
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self._world_config = WorldConfig(time_step_s=self.config.physics_time_step_s)
        self._worlds = WorldCache(self.config.world_cache_size)
        self._entry: CachedWorld | None = None
        self._substeps = self.config.physics_substeps
        self._world: World | None = None
        self._vehicle: Vehicle | None = None
        self._monitor: EventMonitor | None = None
        self.terrain: Terrain | None = None
        self._path: list[tuple[float, float]] = []
        self._renderer = None
        self._perception: DetectorGrid | None = None
        self._oracle: OracleGrid | None = None
        self._sensor_rng: np.random.Generator | None = None

    # -- hooks ---------------------------------------------------------------------------------
    @classmethod
    def default_config(cls) -> EnvConfig:
        """Config used when none is given; scenarios override."""
        return EnvConfig()

    @abc.abstractmethod
    def _make_terrain(self, rng: np.random.Generator) -> Terrain:
        """Build this episode's terrain from the env's generator."""

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._entry = self._acquire_world()
        self.terrain = self._entry.terrain
        self._world, self._vehicle, self._monitor = (
            self._entry.world,
            self._entry.vehicle,
            self._entry.monitor,
        )
        if self.config.start_speed_mps > 0:
            self._vehicle.set_speed(self.config.start_speed_mps)
        self._monitor.reset()
        self._sensor_rng = np.random.default_rng(int(self.np_random.integers(0, 2**63)))
        self._perception = None
        self._oracle = None
        if self.config.observation.source == "detector":
            self._start_perception(observe=False)  # _observe below takes the first frame
        else:
            self._oracle = OracleGrid(self.config.observation, self.terrain)
        self._station = self._station_of(self._vehicle.true_pose())
        pose = self._vehicle.true_pose()
        self._path = [(pose.x, pose.y)]
        self._last_grid = None
        info = self._info(StepEvents(), {}, False)
        return self._observe(), info

    def step(self, action):
        if self._vehicle is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2,):
            raise ActionError(f"action must have shape (2,), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ActionError(f"action must be finite, got {a.tolist()}")
        a = np.clip(a, -1.0, 1.0)
        self._vehicle.apply(max(a[0], 0.0), max(-a[0], 0.0), a[1])
        self._world.step(self._substeps)
        events = self._monitor.poll()
        pose = self._vehicle.true_pose()
        self._path.append((pose.x, pose.y))
        station = self._station_of(pose)
        progress = station - self._station
        self._station = station
        goal = math.dist((pose.x, pose.y), self.terrain.goal_xy_m) <= self.config.goal_radius_m
        rewards = reward_terms(self.config.reward, progress, events, goal)
        terminated = bool(
            events.entered_negative_obstacle or events.trapped or events.collision or events.rollover or goal
        )
        obs = self._observe()
        info = self._info(events, rewards, goal)
        if self.render_mode == "human":
            self.render()
        return obs, float(sum(rewards.values())), terminated, False, info

    def render(self):
        """The top-down frame (``rgb_array``) or show it in a window (``human``); see ``envs.rendering``.

        Shows the terrain overview with the path, and the vehicle-centred grid with the last LiDAR
        frame, the detected and true negative-obstacle outlines and the safety filter's state
        (from :meth:`set_render_overlay`; grey when no filter decided the last step).
        """
        if self.render_mode is None or self._vehicle is None:
            return None
        from negobs_gym.envs.rendering import VehicleFootprint, render_frame

        perception = self._perception
        detection = perception.detection if perception is not None else None
        overlay = getattr(self, "_render_overlay", None)
        cfg = self._vehicle.config
        frame = render_frame(
            self.terrain,
            self._vehicle.true_pose(),
            np.asarray(self._path),
            self._last_grid,
            self.config.observation,
            points_vehicle_m=perception.points_vehicle() if perception is not None else None,
            detected_outlines_m=[o.outline_xy_m for o in detection.obstacles]
            if detection is not None
            else (),
            # only the decision taken for the step that led to this state (see set_render_overlay)
            safety=overlay[1] if overlay is not None and overlay[0] == len(self._path) else None,
            footprint=VehicleFootprint(
                width_m=cfg.width_m, length_m=cfg.length_m, rear_overhang_m=cfg.rear_overhang_m
            ),
        )
        if self.render_mode == "human":
            from negobs_gym.envs.rendering import show_frame

            self._renderer = show_frame(frame, self._renderer)
            return None
        return frame

    def set_render_overlay(self, safety: dict[str, Any] | None) -> None:
        """Show a safety filter's decision for the coming step in :meth:`render` (None clears it).

        :class:`~negobs_gym.safety.BrakingSafetyFilter` calls this before stepping the env, so the
        frames rendered after that step (``human`` mode inside ``step``, or ``RecordVideo`` around
        the filter) show it, whatever the wrapper order. Frames of later steps without a decision
        show no filter state.
        """
        self._render_overlay = None if safety is None else (len(self._path) + 1, dict(safety))

    def close(self) -> None:
        self._close_world()
        if self._renderer is not None:
            import matplotlib.pyplot as plt

            plt.close(self._renderer[0])
            self._renderer = None

    # -- internals -----------------------------------------------------------------------------
    def _close_world(self) -> None:
        self._worlds.close()
        self._world = self._vehicle = self._monitor = self._entry = None

    def _acquire_world(self) -> CachedWorld:
        """This episode's settled world: kept from an earlier episode on the same terrain, or built.

        Without a terrain pool the key is the generator's state before the terrain draw (the
        generator is moved on exactly as a build would); with ``terrain_pool_size`` the terrain is
        the pool's ``k``-th (its own generator seeded with ``k``), ``k`` drawn from the env's.
        """
        pool = self.config.terrain_pool_size
        if pool is None:
            key, terrain_rng = generator_key(self.np_random), self.np_random
        else:
            index = int(self.np_random.integers(pool))
            key, terrain_rng = f"pool-{index}", np.random.default_rng(index)
        entry = self._worlds.get(key)
        if entry is None:
            settle = max(0, round(self.config.settle_time_s / self._world_config.time_step_s))
            entry = build_world(self._make_terrain(terrain_rng), self._world_config, settle)
            if pool is None:
                entry.rng_state_after_terrain = copy.deepcopy(self.np_random.bit_generator.state)
            self._worlds.put(key, entry)
        elif pool is None:
            self.np_random.bit_generator.state = copy.deepcopy(entry.rng_state_after_terrain)
        entry.restore()
        return entry

    def hazard_state(self) -> HazardState:
        """Hazards for :class:`~negobs_gym.safety.BrakingSafetyFilter` (protocol in ``safety.protocol``).

        The negative-obstacle points are the detector's cells, never the ground truth: with an
        oracle observation the first call starts the sensors and detectors, which then run every
        step of the episode.
        """
        if self._vehicle is None:
            raise RuntimeError("call reset() before hazard_state()")
        if self._perception is None:
            self._start_perception()
        cfg = self._vehicle.config
        return HazardState(
            speed_mps=max(0.0, self._vehicle.speed_mps()),
            negative_obstacles_xy_m=self._perception.negative_cells_xy_m(),
            vehicle_width_m=cfg.width_m,
            wheelbase_m=cfg.wheelbase_m,
            max_steer_rad=math.radians(cfg.max_steer_deg),
            dt_s=1.0 / self.config.control_hz,
            max_accel_mps2=cfg.max_drive_force_n / cfg.mass_kg,
            max_brake_decel_mps2=cfg.tyre_mu * BrakingConfig().g_mps2,  # locked wheels: mu g (Eq. 18)
        )

    def _start_perception(self, observe: bool = True) -> None:
        self._perception = DetectorGrid(
            self.config.observation, self._world, self._vehicle, self._sensor_rng, cache=self._entry.extras
        )
        if observe:
            self._last_layers = self._perception.observe(self._world.sim_time_s)

    def _layers(self, pose: Pose) -> dict[str, np.ndarray]:
        if self._perception is not None:
            self._last_layers = self._perception.observe(self._world.sim_time_s)
        if self._oracle is not None:
            return self._oracle.layers(pose)
        return self._last_layers

    def _observe(self) -> dict[str, np.ndarray]:
        pose = self._vehicle.true_pose()
        grid = stack_channels(self._layers(pose), self.config.observation)
        self._last_grid = grid
        state = state_vector(
            self.config.observation,
            pose,
            self._vehicle.speed_mps(),
            self._vehicle.yaw_rate(),
            self._vehicle.steering_angle_rad(),
            np.asarray(self.terrain.goal_xy_m),
        )
        return {"grid": grid, "state": state}

    def _station_of(self, pose: Pose) -> float:
        """Distance along the track centre line of the nearest centre-line point [m]."""
        pts = np.asarray(self.terrain.track.centreline_xy_m, dtype=np.float64)
        a, b = pts[:-1], pts[1:]
        ab = b - a
        p = np.array([pose.x, pose.y])
        t = np.clip(((p - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0.0, 1.0)
        d = np.linalg.norm(a + t[:, None] * ab - p, axis=1)
        k = int(np.argmin(d))
        return float(self.terrain.track.stations_m[k] + t[k] * np.linalg.norm(ab[k]))

    def _distance_to_negative_ahead(self, pose: Pose) -> float:
        """Ground-truth distance from the front bumper to the nearest negative-obstacle vertex ahead."""
        if not self.terrain.negative_obstacles:
            return math.inf
        cfg = self._vehicle.config
        fwd = np.array([-math.sin(pose.yaw), math.cos(pose.yaw)])
        right = np.array([fwd[1], -fwd[0]])
        best = math.inf
        for ob in self.terrain.negative_obstacles:
            rel = np.asarray(ob.outline_xy_m) - np.array([pose.x, pose.y])
            along, across = rel @ fwd, rel @ right
            ahead = along[np.abs(across) <= 0.5 * cfg.track_width_m + 1.0]
            ahead = ahead[ahead > 0]
            if ahead.size:
                best = min(best, float(ahead.min()) - (cfg.length_m - cfg.rear_overhang_m))
        return best

    def _info(self, events: StepEvents, rewards: dict[str, float], goal: bool) -> dict[str, Any]:
        pose = self._vehicle.true_pose()
        return {
            "events": {
                "entered_negative_obstacle": events.entered_negative_obstacle,
                "trapped": events.trapped,
                "collision": events.collision,
                "rollover": events.rollover,
            },
            "distance_to_negative_ahead_m": self._distance_to_negative_ahead(pose),
            "speed_mps": self._vehicle.speed_mps(),
            "pose": pose.as_array(),
            "station_m": self._station,
            "goal_reached": goal,
            "rewards": rewards,
        }
