"""The negobs env: one Gymnasium env driven by a scenario spec, with HighwayEnv-style hooks.

:class:`NegObsEnv` builds each episode from a :class:`~negobs_gym.spec.scenario.ScenarioSpec`
(terrain, obstacles, start, INS noise, physics), observes through a swappable grid source
(:mod:`negobs_gym.envs.sources`), and decides reward, termination, truncation and info in the hooks
:meth:`~NegObsEnv._reward`, :meth:`~NegObsEnv._is_terminated`, :meth:`~NegObsEnv._is_truncated` and
:meth:`~NegObsEnv._info`, which read the spec's reward weights, termination rules and time limit.
The registered envs (:mod:`negobs_gym.envs.scenarios`) are subclasses that only name their spec.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from negobs_gym.core.geometry import PolygonsAhead, project_onto_polyline
from negobs_gym.core.pose import Pose
from negobs_gym.envs.observation import stack_channels, state_space, state_vector
from negobs_gym.envs.outcome import StepOutcome, termination_conditions
from negobs_gym.envs.perception import DetectorGrid
from negobs_gym.envs.rewards import reward_terms
from negobs_gym.envs.sources import DetectorSource, GridSource, make_grid_source
from negobs_gym.envs.world_cache import (
    CachedWorld,
    WorldCache,
    build_world,
    generator_key,
    release_freed_memory,
)
from negobs_gym.errors import ActionError, ConfigError, ResetNeeded
from negobs_gym.safety.braking import BrakingConfig
from negobs_gym.safety.corridor import Corridor
from negobs_gym.safety.decision import SafetyDecision
from negobs_gym.safety.protocol import HazardState
from negobs_gym.sim.events import EventMonitor, StepEvents
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import Vehicle, VehicleConfig
from negobs_gym.sim.world import World
from negobs_gym.spec import SampledScenario, ScenarioSpec, apply_overrides, load_scenario
from negobs_gym.spec.overrides import Overrides

log = logging.getLogger(__name__)

__all__ = ["TRUE_OUTLINE_SPACING_M", "NegObsEnv"]

#: true obstacle outlines are sampled this densely for :meth:`NegObsEnv.true_hazard_distance_m`
#: (its error along the corridor is at most this) [m]
TRUE_OUTLINE_SPACING_M = 0.05


class NegObsEnv(gym.Env):
    """Drive an off-road vehicle past negative obstacles, as a scenario spec describes.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``: ``action[0]`` longitudinal (> 0 throttle, < 0 brake),
    ``action[1]`` steering (+1 = full left). NaN/inf raise :class:`~negobs_gym.errors.ActionError`.
    Control runs at the spec's ``episode.control_hz`` (10 Hz) with physics sub-steps in between.

    ## Observation Space
    ``Dict(grid, state)``: ``grid`` uint8 (channels, rows, cols) in {0, 1}, vehicle-centred
    (rows along +Y from the rear, cols along +X from the left), channels from
    ``ObservationConfig.channels``; ``state`` float32 (speed, yaw rate, steering angle, goal x, goal
    y in the vehicle frame, then the route points of ``ObservationConfig.route_points_m``).

    ## Rewards
    Weighted terms by name in ``info["rewards"]`` (weights: the spec's ``[reward]``): progress
    along the track, negative-obstacle entry, collision/rollover, time, goal, stopped before a
    hazard, trapped.

    ## Episode End
    Terminates when a rule named in the spec's ``terminations`` fires (``info["termination"]``
    lists them); truncates after ``episode.time_limit_s`` whether made through the registry or
    built directly.

    ## Arguments
    ``scenario``: a :class:`ScenarioSpec`, a shipped scenario's name or a TOML path (subclasses
    name their own). ``overrides``: single settings of that spec changed, as the commands' ``--set``
    paths, either ``"KEY.PATH=VALUE"`` strings or a mapping ``{"observation.source": "oracle"}``
    (:func:`negobs_gym.spec.apply_overrides`). ``render_mode``: ``"rgb_array"`` or ``"human"``.

    ## Info
    ``events`` (dict), ``distance_to_negative_ahead_m`` and ``distance_to_positive_ahead_m``
    (ground truth from the front bumper, in the wheels' strip; inf if none), ``speed_mps``,
    ``pose`` (float64 array x, y, z, roll, pitch, yaw; ``Pose.from_array`` restores it),
    ``rewards``, ``station_m``, ``goal_reached``, ``stopped``, ``off_track``, ``termination``.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "human"], "render_fps": 10}  # noqa: RUF012 - gymnasium API

    #: Scenario used when none is passed (subclasses name their registered spec).
    default_scenario: str | None = None

    def __init__(
        self,
        config: object = None,
        render_mode: str | None = None,
        *,
        scenario: ScenarioSpec | str | None = None,
        overrides: Overrides = (),
    ) -> None:
        if config is not None:  # the removed episode-config object, passed by older code
            raise ConfigError(
                "config",
                "envs are built from a scenario spec plus overrides: pass scenario=SPEC_OR_NAME and/or "
                "overrides={'observation.source': 'oracle', 'episode.time_limit_s': 20} (the --set paths)",
            )
        scenario = scenario if scenario is not None else self.default_scenario
        if scenario is None:
            raise ConfigError("scenario", "NegObsEnv needs a scenario spec, a shipped name or a TOML path")
        #: The spec this env runs; the one description of its episodes (read-only).
        self.scenario: ScenarioSpec = apply_overrides(load_scenario(scenario), overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(
                "render_mode", f"must be one of {self.metadata['render_modes']}, got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.scenario.episode.control_hz}
        self._grid_source: GridSource = make_grid_source(self.scenario.observation)
        self.observation_space = spaces.Dict(
            {"grid": self._grid_source.space(), "state": state_space(self.scenario.observation)}
        )
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        physics = self.scenario.physics
        self._substeps = max(1, round(1.0 / (self.scenario.episode.control_hz * physics.time_step_s)))
        self._worlds = WorldCache(self.scenario.episode.world_cache_size)
        self._entry: CachedWorld | None = None
        self._env_steps = 0  # steps since the env was made, over episodes (ObservationConfig.scan_clock)
        self._world: World | None = None
        self._vehicle: Vehicle | None = None
        self._monitor: EventMonitor | None = None
        self._detector: DetectorSource | None = None
        self.terrain: Terrain | None = None
        self._path: list[tuple[float, float]] = []
        self._renderer = None
        self._render_overlay = None

    @classmethod
    def default_spec(cls) -> ScenarioSpec:
        """The scenario spec this env runs by default (to read, or to change with overrides)."""
        if cls.default_scenario is None:
            raise ConfigError("scenario", f"{cls.__name__} has no default scenario")
        return load_scenario(cls.default_scenario)

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        evictions = self._worlds.evictions
        self._entry = self._acquire_world()
        episode = self._entry.episode
        self.terrain = episode.terrain
        self._negatives_ahead = PolygonsAhead([ob.outline_xy_m for ob in self.terrain.negative_obstacles])
        bodies = [ob.footprint_xy_m for ob in self.terrain.positive_obstacles if not ob.in_heightfield]
        self._positives_ahead = PolygonsAhead(bodies)
        entry = self._entry
        self._world, self._vehicle, self._monitor = entry.world, entry.vehicle, entry.monitor
        if self.scenario.ins.noisy:  # drawn only then, so noise-free specs keep their draws
            self._vehicle.use_ins_rng(np.random.default_rng(int(self.np_random.integers(0, 2**63))))
        if episode.start_speed_mps > 0:
            self._vehicle.set_speed(episode.start_speed_mps)
        self._monitor.reset()
        self._sensor_rng = np.random.default_rng(int(self.np_random.integers(0, 2**63)))
        self._grid_source.start(self._world, self._vehicle, self.terrain, self._sensor_rng, entry.extras)
        self._detector = self._grid_source if isinstance(self._grid_source, DetectorSource) else None
        if self._worlds.evictions > evictions:  # the dropped world's last references are gone now
            release_freed_memory()
        self._steps = 0
        self._applied: np.ndarray | None = None  # the last step's clipped action, for the frames' caption
        self._still_s = 0.0
        self._entered = False
        self._stop_rewarded = False
        pose = self._vehicle.true_pose()
        self._station, _ = self._track_position(pose)
        self._goal_gap_m = self._capped_goal_distance(pose)
        self._path = [(pose.x, pose.y)]
        self._last_grid = None
        obs = self._observe()
        self._align_frames()
        return obs, self._info(StepOutcome(events=StepEvents()), {}, ())

    def _sample_episode(self, rng: np.random.Generator) -> SampledScenario:
        """This episode's terrain, start pose and speed: the spec's ranges drawn from ``rng``."""
        return self.scenario.sample(rng)

    def _acquire_world(self) -> CachedWorld:
        """This episode's settled world: kept from an earlier episode on the same draw, held ahead
        (:meth:`build_ahead`), or built.

        Without a terrain pool the key is the generator's state before the spec is drawn (after a
        hit the generator is moved on exactly as the draw would have); with
        ``episode.terrain_pool_size`` the episode is the pool's ``k``-th draw (its own generator
        seeded with ``k``), ``k`` drawn from the env's. Every episode starts from the settled
        state saved after the build, so a kept world gives the same episode bit for bit.
        """
        key, draw_rng = self._draw_key(self.np_random)
        entry = self._worlds.get(key)
        if entry is None:
            entry = self._build_world(draw_rng)
            self._worlds.put(key, entry)
        elif self.scenario.episode.terrain_pool_size is None:
            self.np_random.bit_generator.state = copy.deepcopy(entry.rng_state_after_draw)
        entry.restore()
        return entry

    def world_cache_counts(self) -> dict[str, int]:
        """The world cache's counters (:meth:`~negobs_gym.envs.world_cache.WorldCache.counts`): how
        many resets found their world kept or built ahead, how many built it."""
        return self._worlds.counts()

    def _draw_key(self, rng: np.random.Generator) -> tuple[str, np.random.Generator]:
        """The world key of the episode that ``rng`` draws next, and the generator that draws it."""
        pool = self.scenario.episode.terrain_pool_size
        if pool is None:
            return generator_key(rng), rng
        index = int(rng.integers(pool))
        return f"pool-{index}", np.random.default_rng(index)

    def _build_world(self, draw_rng: np.random.Generator) -> CachedWorld:
        """Draw the episode from ``draw_rng`` and build, settle and save its world."""
        spec = self.scenario
        episode = self._sample_episode(draw_rng)
        vehicle_config = VehicleConfig(
            ins_position_noise_m=spec.ins.position_noise_m, ins_angle_noise_deg=spec.ins.angle_noise_deg
        )
        settle_steps = max(0, round(spec.episode.settle_time_s / spec.physics.time_step_s))
        entry = build_world(episode, spec.physics, vehicle_config, settle_steps)
        if self.scenario.episode.terrain_pool_size is None:
            entry.rng_state_after_draw = copy.deepcopy(draw_rng.bit_generator.state)
        return entry

    def build_ahead(self) -> bool:
        """Build now the world that the next reset without a seed will use, with the grid source's
        products of it (the ray caster), so that reset costs what a reset onto a kept world costs.

        For idle time: a vector-env worker calls it while it waits
        (:class:`~negobs_gym.envs.build_ahead.BuildAheadVecEnv`). Nothing an episode shows changes:
        the reset takes the world as it takes a kept one, the same episode bit for bit, and a reset
        with a seed (another draw) closes it. Holds one more world in memory until then.

        Returns:
            Whether a world was built: False before the first reset (a seed will decide), or when
            the next draw's world is already kept or held.
        """
        if self._entry is None:
            return False
        rng = copy.deepcopy(self.np_random)
        key, draw_rng = self._draw_key(rng)
        if key in self._worlds:
            return False
        entry = self._build_world(draw_rng)
        self._grid_source.prepare(entry.world, entry.vehicle, entry.extras)
        self._worlds.hold_ahead(key, entry)
        return True

    def step(self, action):
        if self._vehicle is None:
            raise ResetNeeded("call reset() before step()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2,):
            raise ActionError(f"action must have shape (2,), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ActionError(f"action must be finite, got {a.tolist()}")
        a = np.clip(a, -1.0, 1.0)
        self._applied = a
        self._vehicle.apply(max(a[0], 0.0), max(-a[0], 0.0), a[1])
        self._world.step(self._substeps)
        self._steps += 1
        self._env_steps += 1
        outcome = self._outcome(self._monitor.poll())
        rewards = self._reward(outcome)
        fired = self._is_terminated(outcome)
        obs = self._observe()
        info = self._info(outcome, rewards, fired)
        if self.render_mode == "human":
            self.render()
        return obs, float(sum(rewards.values())), bool(fired), self._is_truncated(), info

    # -- hooks (HighwayEnv style; they read the spec) ------------------------------------------
    def _reward(self, outcome: StepOutcome) -> dict[str, float]:
        """Reward terms by name, weighted by the spec's ``[reward]``; the reward is their sum."""
        rewards = reward_terms(self.scenario.reward, outcome, self._stop_rewarded)
        self._stop_rewarded = self._stop_rewarded or outcome.stopped_before_hazard
        return rewards

    def _is_terminated(self, outcome: StepOutcome) -> tuple[str, ...]:
        """Names of the spec's termination rules that fired this step (empty: go on)."""
        fired = termination_conditions(outcome)
        return tuple(name for name in self.scenario.terminations if fired[name])

    def _is_truncated(self) -> bool:
        """True once the spec's time limit (``episode.time_limit_s``) has run out."""
        return self._steps >= self.scenario.episode.max_episode_steps

    def _info(
        self, outcome: StepOutcome, rewards: dict[str, float], termination: tuple[str, ...]
    ) -> dict[str, Any]:
        """The info dict of ``reset`` and ``step`` (ground truth for evaluation, see the class doc)."""
        pose = self._vehicle.true_pose()
        events = outcome.events
        return {
            "events": {
                "entered_negative_obstacle": events.entered_negative_obstacle,
                "trapped": events.trapped,
                "collision": events.collision,
                "rollover": events.rollover,
            },
            "distance_to_negative_ahead_m": self._distance_to_negative_ahead(pose),
            "distance_to_positive_ahead_m": self._distance_to_positive_ahead(pose),
            "speed_mps": self._vehicle.speed_mps(),
            "pose": pose.as_array(),
            "station_m": self._station,
            "goal_reached": outcome.goal,
            "stopped": outcome.stopped,
            "off_track": outcome.off_track,
            "termination": list(termination),
            "rewards": rewards,
        }

    def _outcome(self, events: StepEvents) -> StepOutcome:
        """Ground-truth judgement of the step just simulated (progress, goal, stop, off track)."""
        task = self.scenario.task
        pose = self._vehicle.true_pose()
        self._path.append((pose.x, pose.y))
        station, lateral = self._track_position(pose)
        progress = station - self._station
        self._station = station
        self._entered = self._entered or bool(events.entered_negative_obstacle)
        speed = self._vehicle.speed_mps()
        self._still_s = (
            self._still_s + 1.0 / self.scenario.episode.control_hz
            if abs(speed) < task.stop_speed_mps
            else 0.0
        )
        stopped = self._still_s >= task.stop_hold_s and not self._entered
        goal_gap = self._capped_goal_distance(pose)
        approach, self._goal_gap_m = self._goal_gap_m - goal_gap, goal_gap
        return StepOutcome(
            events=events,
            progress_m=progress,
            goal=math.dist((pose.x, pose.y), self.terrain.goal_xy_m) <= task.goal_radius_m,
            stopped=stopped,
            stopped_before_hazard=stopped and self._distance_to_negative_ahead(pose) <= task.stop_window_m,
            off_track=lateral > 0.5 * self.terrain.track.width_m,
            goal_approach_m=approach,
        )

    def _capped_goal_distance(self, pose: Pose) -> float:
        """The straight-line distance to the goal, capped at ``goal_approach_radius_m`` [m]."""
        radius = self.scenario.reward.goal_approach_radius_m
        return min(math.dist((pose.x, pose.y), self.terrain.goal_xy_m), radius)

    @property
    def vehicle(self) -> Vehicle | None:
        """The simulated vehicle of the running episode (None before ``reset``)."""
        return self._vehicle

    @property
    def max_perception_age_s(self) -> float:
        """The oldest :meth:`hazard_state` data gets between two LiDAR frames [s]: 0 with a frame
        every step, ``(scan_every - 1) / control_hz`` with ``ObservationConfig.scan_every`` (the
        safety filter's ``perception_timeout_s`` counts from there)."""
        return (self.scenario.observation.scan_every - 1) / self.scenario.episode.control_hz

    @property
    def perception(self) -> DetectorGrid | None:
        """The running LiDAR rig and detectors (last scans and detection), or None before they start."""
        return self._detector.perception if self._detector is not None else None

    # -- rendering -----------------------------------------------------------------------------
    def render(self):
        """The top-down frame (``rgb_array``) or show it in a window (``human``); see ``envs.rendering``.

        Shows the terrain overview with the path, and the vehicle-centred grid with the last LiDAR
        frame, the detected and true negative-obstacle outlines and the safety filter's state
        (from :meth:`set_render_overlay`; grey when no filter decided the last step). Layout: the
        spec's ``[render]`` settings.
        """
        if self.render_mode is None or self._vehicle is None:
            return None
        from negobs_gym.envs.rendering import VehicleFootprint, caption_lines, render_frame

        perception = self.perception
        overlay = self._render_overlay
        # only the decision taken for the step that led to this state (see set_render_overlay)
        safety, decision_pose = (
            overlay[1:] if overlay is not None and overlay[0] == len(self._path) else (None, None)
        )
        cfg = self._vehicle.config
        frame = render_frame(
            self.terrain,
            self._vehicle.true_pose(),
            np.asarray(self._path),
            self._last_grid,
            self.scenario.observation,
            points_vehicle_m=perception.points_vehicle() if perception is not None else None,
            detected_outlines_m=perception.detected_outlines() if perception is not None else (),
            safety=safety,
            decision_pose=decision_pose,
            footprint=VehicleFootprint(
                width_m=cfg.width_m, length_m=cfg.length_m, rear_overhang_m=cfg.rear_overhang_m
            ),
            config=self.scenario.render,
            caption=caption_lines(
                self._steps / self.scenario.episode.control_hz,
                self._vehicle.speed_mps(),
                self._applied,
                safety,
            ),
        )
        if self.render_mode == "human":
            from negobs_gym.envs.rendering import show_frame

            self._renderer = show_frame(frame, self._renderer)
            return None
        return frame

    def set_render_overlay(self, decision: SafetyDecision | None) -> None:
        """Show a safety filter's decision for the coming step in :meth:`render` (None clears it).

        :class:`~negobs_gym.safety.BrakingSafetyFilter` calls this before stepping the env, so the
        frames rendered after that step (``human`` mode inside ``step``, or ``RecordVideo`` around
        the filter) show it, whatever the wrapper order. Frames of later steps without a decision
        show no filter state.
        """
        pose = self._vehicle.true_pose() if self._vehicle is not None else None  # where it decided
        self._render_overlay = None if decision is None else (len(self._path) + 1, decision, pose)

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

    def hazard_state(self) -> HazardState:
        """Hazards for :class:`~negobs_gym.safety.BrakingSafetyFilter` (protocol in ``safety.protocol``).

        The negative- and positive-obstacle points are the detector's cells, never the ground truth: with an
        oracle observation the first call starts the sensors and detectors, which then run every
        step of the episode. With the ``pem`` source they are the PEM's own cells (its ``negative``
        layer and the oracle's ``positive``, :class:`~negobs_gym.envs.sources.PemSource`).
        """
        if self._vehicle is None:
            raise ResetNeeded("call reset() before hazard_state()")
        seen = self._grid_source.hazards()  # the detectors', or the PEM source's own cells
        if seen is None:
            if self._detector is None:
                self._start_detector()
            seen = self._detector.perception
        cfg = self._vehicle.config
        return HazardState(
            speed_mps=max(0.0, self._vehicle.speed_mps()),
            negative_obstacles_xy_m=seen.negative_cells_xy_m(),
            positive_obstacles_xy_m=seen.positive_cells_xy_m(),
            **cfg.hazard_geometry(BrakingConfig().g_mps2),
            dt_s=1.0 / self.scenario.episode.control_hz,
            time_s=self._world.sim_time_s,
            perception_time_s=seen.stamp_s,
            observed=seen.observed,  # coverage, for the governed filter
            grid=self.scenario.observation.grid,
            pose=seen.pose,
        )

    def _start_detector(self) -> None:
        """Detectors beside an oracle grid, for the hazards only (they then run every step)."""
        detector_obs = dataclasses.replace(self.scenario.observation, source="detector")
        self._detector = DetectorSource(detector_obs)
        self._detector.start(self._world, self._vehicle, self.terrain, self._sensor_rng, self._entry.extras)
        self._detector.layers(self._world.sim_time_s)
        self._align_frames()

    def sync_scan_clock(self, env_steps: int) -> None:
        """Set the step count that ``ObservationConfig.scan_clock = "env"`` puts the frames on to
        ``env_steps`` and move the next frames onto it (no effect with the episode clock).

        A vector env whose slots swap processes (:class:`~negobs_gym.envs.vector.PrefetchVecEnv`:
        a spare resets the next episode without stepping) calls it with its own step count when
        a process takes over a slot, so that all its slots cast on the same steps.
        """
        if isinstance(env_steps, bool) or not isinstance(env_steps, (int, np.integer)) or env_steps < 0:
            raise ConfigError("env_steps", f"must be an int >= 0, got {env_steps!r}")
        self._env_steps = int(env_steps)
        self._align_frames()

    def _align_frames(self) -> None:
        """After a first frame: put the next ones on the env's step clock where the config asks."""
        if self._detector is not None and self.scenario.observation.scan_clock == "env":
            self._detector.perception.align_frames(self._env_steps)

    def _observe(self) -> dict[str, np.ndarray]:
        t = self._world.sim_time_s
        if self._detector is not None and self._detector is not self._grid_source:
            self._detector.layers(t)  # keep the hazard detectors' history going
        grid = stack_channels(self._grid_source.layers(t), self.scenario.observation)
        self._last_grid = grid
        pose = self._vehicle.true_pose()
        state = state_vector(
            self.scenario.observation,
            pose,
            self._vehicle.speed_mps(),
            self._vehicle.yaw_rate(),
            self._vehicle.steering_angle_rad(),
            np.asarray(self.terrain.goal_xy_m),
            self._route_points(),
        )
        return {"grid": grid, "state": state}

    def _route_points(self) -> np.ndarray | None:
        """World xy of the centre-line points ``observation.route_points_m`` ahead of the vehicle's
        station (None when the observation has none); beyond the track's end they stay at its end."""
        ahead = self.scenario.observation.route_points_m
        if not ahead:
            return None
        track = self.terrain.track
        stations = np.minimum(self._station + np.asarray(ahead), track.stations_m[-1])
        xy, _ = track.pose_at(stations)
        return xy

    def _track_position(self, pose: Pose) -> tuple[float, float]:
        """(station along the centre line [m], distance from it [m]) of the nearest centre-line point."""
        station, distance = project_onto_polyline(
            np.array([pose.x, pose.y]), self.terrain.track.centreline_xy_m
        )
        return float(station), float(distance)

    def _distance_to_negative_ahead(self, pose: Pose) -> float:
        """Ground-truth distance from the front bumper to the nearest negative-obstacle outline
        point ahead within the wheels' strip (track width + 1 m each side), inf if none."""
        return self._distance_ahead(self._negatives_ahead, pose)

    def _distance_to_positive_ahead(self, pose: Pose) -> float:
        """The same for the footprints of the positive obstacles the car can hit (bodies; mounds,
        part of the ground, are not)."""
        return self._distance_ahead(self._positives_ahead, pose)

    def true_hazard_distance_m(
        self,
        corridor: Corridor,
        pose: Pose | np.ndarray,
        channel: Literal["negative", "positive"] = "negative",
    ) -> float:
        """Ground truth of a safety filter's hazard distance: arc length along ``corridor`` (laid
        out from ``pose``, as the filter's decision at that pose did) to the nearest true outline
        of ``channel``'s obstacles (negative: the pits' rims; positive: the footprints of the bodies
        the car can hit), sampled every :data:`TRUE_OUTLINE_SPACING_M`; inf when none lies in it.

        The evaluation's check of a veto (``ScenarioResult.false_vetoes``) compares this with the
        distance the filter acted on. ``pose``: a :class:`Pose` or the array of ``info["pose"]``.
        """
        if channel not in ("negative", "positive"):
            raise ConfigError("channel", f"expected 'negative' or 'positive', got {channel!r}")
        pose = pose if isinstance(pose, Pose) else Pose.from_array(np.asarray(pose, dtype=np.float64))
        polygons = self._negatives_ahead if channel == "negative" else self._positives_ahead
        points = polygons.outline_points(np.array([pose.x, pose.y]), pose.yaw, TRUE_OUTLINE_SPACING_M)
        return corridor.hazard_distance_m(points)

    def _distance_ahead(self, polygons: PolygonsAhead, pose: Pose) -> float:
        """Front bumper to the nearest point of ``polygons`` ahead in the wheels' strip."""
        cfg = self._vehicle.config
        half = 0.5 * cfg.track_width_m + 1.0
        front_m = cfg.length_m - cfg.rear_overhang_m
        return polygons.nearest_ahead(np.array([pose.x, pose.y]), pose.yaw, half) - front_m
