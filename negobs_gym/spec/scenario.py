"""The scenario spec: one frozen, validated description of a scripted scenario.

A spec names the terrain (a preset from :data:`negobs_gym.sim.presets.PRESETS` with its parameters,
or a course as :class:`~negobs_gym.sim.terrain.TerrainConfig` fields), an explicit list of negative
and positive obstacles on that course, the start state, the episode length, the task, the reward
weights and termination rules by name, the observation, INS noise, physics and render settings, the
default driver of ``negobs scenario run`` and the pass criteria of a scripted test. Numeric obstacle,
start and preset parameters may be ranges ``[low, high]``, drawn at each reset from the env's
seeded generator (:meth:`ScenarioSpec.sample`). Specs load from TOML (:func:`spec_from_toml`) or a
dict (:meth:`ScenarioSpec.from_dict`); :meth:`ScenarioSpec.to_dict` gives the dict back.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, get_args

import numpy as np
import tomllib

from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, require
from negobs_gym.safety.config import SafetyFilterConfig
from negobs_gym.sim.carving import NegativeObstacleSpec, PositiveObstacleSpec
from negobs_gym.sim.presets import PRESETS
from negobs_gym.sim.terrain import TerrainConfig, generate_terrain
from negobs_gym.sim.types import Terrain
from negobs_gym.spec.fields import Range, from_plain, to_plain
from negobs_gym.spec.observation import ObservationConfig
from negobs_gym.spec.physics import EnvPhysicsConfig
from negobs_gym.spec.render import RenderConfig
from negobs_gym.spec.reward import RewardConfig
from negobs_gym.spec.toml_out import dumps_toml

__all__ = [
    "TERMINATION_RULES",
    "CriteriaSpec",
    "EpisodeSpec",
    "InsSpec",
    "NegativeObstacleEntry",
    "PositiveObstacleEntry",
    "RunSpec",
    "SampledScenario",
    "ScenarioSpec",
    "StartSpec",
    "TaskSpec",
    "TerrainSpec",
    "spec_from_toml",
    "spec_to_toml",
]

Number = float | Range
TaskKind = Literal["reach_goal", "stop_before_hazard", "cross", "follow"]
TerminationRule = Literal[
    "entered_negative_obstacle", "trapped", "collision", "rollover", "goal", "stopped", "off_track"
]
#: Names a spec's ``terminations`` may list (see :mod:`negobs_gym.envs.hooks`).
TERMINATION_RULES: tuple[str, ...] = get_args(TerminationRule)
DriverName = Literal[
    "reckless", "constant_speed", "pure_pursuit", "track_planner", "creeping", "grid_planner"
]
PolicyAlgo = Literal["PPO", "SAC"]  # negobs_gym.policies.config.ALGORITHMS


def _finite(value: object) -> bool:
    """A real number (not a bool) that is finite."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _draw(value: Number, rng: np.random.Generator) -> float:
    return value.sample(rng) if isinstance(value, Range) else float(value)


def _corners(obj: Any, names: tuple[str, ...]) -> tuple[dict[str, float], dict[str, float]]:
    """The fields ``names`` with every range at its low end, and at its high end."""

    def end(value: Number, which: str) -> float:
        return getattr(value, which) if isinstance(value, Range) else value

    low, high = ({n: end(getattr(obj, n), which) for n in names} for which in ("low", "high"))
    return low, high


def _draw_fields(obj: Any, names: tuple[str, ...], rng: np.random.Generator) -> dict[str, float]:
    """Every field drawn, in ``names`` order (one number from ``rng`` per ranged field)."""
    return {n: _draw(getattr(obj, n), rng) for n in names}


@dataclass(frozen=True, kw_only=True)
class NegativeObstacleEntry:
    """A negative obstacle on the course; numbers may be ranges. Meaning as in
    :class:`~negobs_gym.sim.carving.NegativeObstacleSpec` (``station_m`` = centre along the track)."""

    kind: str = "pit"
    length_m: Number = 1.0  # along the track [m]
    width_m: Number = 0.5  # across the track [m]
    depth_m: Number = 0.8  # rim to floor [m]
    wall_slope_deg: Number = 90.0  # 90 = vertical walls
    station_m: Number  # centre, along the track from the start [m]
    lateral_m: Number = 0.0  # centre offset, + right [m]
    yaw_deg: Number = 0.0  # relative to the track heading

    _NUMBERS = ("length_m", "width_m", "depth_m", "wall_slope_deg", "station_m", "lateral_m", "yaw_deg")

    def __post_init__(self) -> None:
        for corner in _corners(self, self._NUMBERS):  # both ends of every range must be valid
            NegativeObstacleSpec(kind=self.kind, **corner)

    def sample(self, rng: np.random.Generator) -> NegativeObstacleSpec:
        """The obstacle with its ranges drawn from ``rng``."""
        return NegativeObstacleSpec(kind=self.kind, **_draw_fields(self, self._NUMBERS, rng))


@dataclass(frozen=True, kw_only=True)
class PositiveObstacleEntry:
    """A positive obstacle on the course (as :class:`~negobs_gym.sim.carving.PositiveObstacleSpec`)."""

    kind: str = "rock"
    station_m: Number
    lateral_m: Number = 0.0
    yaw_deg: Number = 0.0
    size_m: tuple[float, float, float] | None = None  # None: the kind's default size

    _NUMBERS = ("station_m", "lateral_m", "yaw_deg")

    def __post_init__(self) -> None:
        for corner in _corners(self, self._NUMBERS):
            PositiveObstacleSpec(kind=self.kind, size_m=self.size_m, **corner)

    def sample(self, rng: np.random.Generator) -> PositiveObstacleSpec:
        """The obstacle with its ranges drawn from ``rng``."""
        return PositiveObstacleSpec(
            kind=self.kind, size_m=self.size_m, **_draw_fields(self, self._NUMBERS, rng)
        )


def _param_range(name: str, value: list | tuple) -> Range:
    """A preset parameter given as ``[low, high]``."""
    try:
        require(len(value) == 2, "range", "a list must be [low, high]")
        return from_plain(Range, {"low": value[0], "high": value[1]})
    except ConfigError as exc:
        raise ConfigError(f"params.{name}", f"must be a number or [low, high], got {list(value)!r}") from exc


def _check_param(name: str, value: Any, annotation: str) -> None:
    """A preset parameter against the preset's annotation (``float``, ``int``, ``bool``, ...)."""
    finite = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    kinds = {
        "bool": (isinstance(value, bool), "true or false"),
        "int": (isinstance(value, int) and not isinstance(value, bool), "an integer"),
        "float": (finite or isinstance(value, Range), "a finite number or [low, high]"),
        "float | None": (finite or isinstance(value, Range), "a finite number or [low, high]"),
    }
    ok, expected = kinds.get(annotation, (True, ""))
    require(ok, f"params.{name}", f"must be {expected}, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class TerrainSpec:
    """Either ``preset`` (a name in :data:`~negobs_gym.sim.presets.PRESETS`) with ``params``, or a
    ``course`` (TerrainConfig fields without obstacles; the spec's obstacle lists go on it)."""

    preset: str | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    course: TerrainConfig | None = None

    def __post_init__(self) -> None:
        require(
            (self.preset is None) != (self.course is None),
            "preset",
            "give exactly one of preset (with params) or course",
        )
        params = dict(self.params)
        if self.preset is not None:
            require(
                self.preset in PRESETS, "preset", f"unknown preset {self.preset!r}; one of {sorted(PRESETS)}"
            )
            signature = inspect.signature(PRESETS[self.preset]).parameters
            accepted = set(signature) - {"seed"}
            for name, value in params.items():
                require(
                    name in accepted,
                    f"params.{name}",
                    f"not a parameter of {self.preset} (the env draws the seed); one of {sorted(accepted)}",
                )
                if isinstance(value, (list, tuple)):
                    params[name] = _param_range(name, value)
                _check_param(name, params[name], str(signature[name].annotation))
        else:
            require(not params, "params", "params belong to a preset; a course takes its fields directly")
            require(
                not self.course.negative_obstacles and not self.course.positive_obstacles,
                "course",
                "list obstacles in the spec's [[obstacles]] / [[positive_obstacles]], not in the course",
            )
        object.__setattr__(self, "params", params)


@dataclass(frozen=True, kw_only=True)
class StartSpec:
    """Start pose in track coordinates and the initial forward speed; numbers may be ranges."""

    station_m: Number = 0.0  # along the track [m]
    lateral_m: Number = 0.0  # + right of the centre line [m]
    yaw_deg: Number = 0.0  # relative to the track heading, + left
    speed_mps: Number = 0.0  # paper N §4 braking scenes start at 25 km/h = 6.944 m/s

    _NUMBERS = ("station_m", "lateral_m", "yaw_deg", "speed_mps")

    def __post_init__(self) -> None:
        for corner in _corners(self, self._NUMBERS):
            require(corner["speed_mps"] >= 0, "speed_mps", f"must be >= 0, got {corner['speed_mps']!r}")
            require(corner["station_m"] >= 0, "station_m", f"must be >= 0, got {corner['station_m']!r}")


@dataclass(frozen=True, kw_only=True)
class EpisodeSpec:
    """Episode timing and the worlds kept between episodes."""

    control_hz: float = 10.0  # paper N: the LiDARs spin at 10 Hz, control runs with them
    time_limit_s: float = 30.0  # truncation [s]
    settle_time_s: float = 0.25  # suspension settling at reset [s]
    # settled worlds kept between episodes: a reset onto a kept terrain restores it in
    # milliseconds instead of building it (~1.2 s; negobs_gym.envs.world_cache)
    world_cache_size: int = 1
    # None: a new terrain each episode; k: episodes draw one of k fixed terrains (terrain i is the
    # spec's terrain from default_rng(i)), cheap to reset once cached (Procgen-style levels)
    terrain_pool_size: int | None = None

    def __post_init__(self) -> None:
        require(
            _finite(self.control_hz) and 1.0 <= self.control_hz <= 60.0, "control_hz", "must be in [1, 60] Hz"
        )
        require(_finite(self.time_limit_s) and self.time_limit_s > 0, "time_limit_s", "must be > 0 [s]")
        require(_finite(self.settle_time_s) and self.settle_time_s >= 0, "settle_time_s", "must be >= 0 [s]")
        require(
            type(self.world_cache_size) is int and self.world_cache_size >= 1,
            "world_cache_size",
            f"must be an int >= 1, got {self.world_cache_size!r}",
        )
        require(
            self.terrain_pool_size is None
            or (type(self.terrain_pool_size) is int and self.terrain_pool_size >= 1),
            "terrain_pool_size",
            f"must be None or an int >= 1, got {self.terrain_pool_size!r}",
        )

    @property
    def max_episode_steps(self) -> int:
        """Control steps before truncation."""
        return max(1, round(self.time_limit_s * self.control_hz))


@dataclass(frozen=True, kw_only=True)
class TaskSpec:
    """What the scenario asks of the driver and how ``stopped`` is judged.

    Attributes:
        kind: ``reach_goal``, ``stop_before_hazard`` (stop short of the negative obstacle ahead),
            ``cross`` (get over the obstacles to the goal without being trapped) or ``follow``
            (drive the track to the goal without leaving it); decides a run's ``task_done``
            (:class:`negobs_gym.eval.scenario_runner.ScenarioResult`).
        goal_radius_m: The goal counts as reached within this distance [m].
        stop_speed_mps: Below this speed the vehicle is standing [m/s].
        stop_hold_s: ``stopped`` holds after standing this long without entering a negative
            obstacle [s] (the suspension rocks the car for a moment after a full brake).
        stop_window_m: The ``stopped`` reward needs a negative obstacle at most this far ahead of
            the bumper [m]: stopping far from any hazard is not the task. Default: R(25 km/h) of
            paper N Eq. 18 (10.52 m), rounded up.
    """

    kind: TaskKind = "reach_goal"
    goal_radius_m: float = 3.0
    stop_speed_mps: float = 0.1
    stop_hold_s: float = 1.0
    stop_window_m: float = 11.0

    def __post_init__(self) -> None:
        for name in ("goal_radius_m", "stop_speed_mps", "stop_window_m"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value!r}")
        require(math.isfinite(self.stop_hold_s) and self.stop_hold_s >= 0, "stop_hold_s", "must be >= 0")


@dataclass(frozen=True, kw_only=True)
class InsSpec:
    """1-sigma Gaussian noise of the INS pose the detectors get (0 = exact, the default)."""

    position_noise_m: float = 0.0
    angle_noise_deg: float = 0.0

    def __post_init__(self) -> None:
        for name in ("position_noise_m", "angle_noise_deg"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, name, f"must be finite and >= 0, got {value!r}")

    @property
    def noisy(self) -> bool:
        """True when either noise is on."""
        return self.position_noise_m > 0 or self.angle_noise_deg > 0


@dataclass(frozen=True, kw_only=True)
class RunSpec:
    """Defaults of ``negobs scenario run``: the scripted driver (or a trained policy) and whether
    the safety filter guards it."""

    driver: DriverName = "reckless"
    # a trained policy drives instead of `driver`: a saved stable-baselines3 model's path or a
    # shipped policy's name (`negobs policy list`); empty: the scripted driver
    policy: str = ""
    policy_algo: PolicyAlgo = "PPO"  # the algorithm that saved `policy`
    filter: bool = True  # the safety filter guards the run, as the spec's [filter] table sets it
    target_speed_mps: float = 25.0 / 3.6  # paper N §4: 25 km/h
    lane_offset_m: float = 0.0  # pure pursuit follows the centre line shifted this far right [m]
    # settings of the scripted driver's config, nested as its fields are (the grid planner's
    # heading lattice: `[run.driver_settings.planner] bend_steps = 1`, or `--set
    # run.driver_settings.planner.bend_steps=1`); checked when the driver is built, as
    # negobs_gym.drivers.make_driver applies them. Empty: the driver's defaults
    driver_settings: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        require(
            math.isfinite(self.lane_offset_m), "lane_offset_m", f"must be finite, got {self.lane_offset_m!r}"
        )
        require(
            math.isfinite(self.target_speed_mps) and self.target_speed_mps > 0,
            "target_speed_mps",
            f"must be finite and > 0, got {self.target_speed_mps!r}",
        )


@dataclass(frozen=True, kw_only=True)
class CriteriaSpec:
    """Pass criteria of a scripted run; unset (None) criteria are not checked.

    Booleans must equal the run's outcome; ``min_``/``max_`` values bound it. See
    :class:`negobs_gym.eval.scenario_runner.ScenarioResult` for the measured quantities.
    """

    task_done: bool | None = None
    entered_negative_obstacle: bool | None = None
    stopped_before: bool | None = None
    min_stop_margin_m: float | None = None
    max_stop_margin_m: float | None = None
    min_positive_gap_m: float | None = None
    collision: bool | None = None
    goal_reached: bool | None = None
    left_track: bool | None = None
    max_decel_mps2: float | None = None
    max_vetoes: int | None = None
    max_false_vetoes: int | None = None
    max_missed_vetoes: int | None = None
    max_veto_error_m: float | None = None
    max_time_s: float | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name.startswith(("min_", "max_")) and value is not None:
                require(
                    isinstance(value, (int, float)) and math.isfinite(value) and value >= 0,
                    f.name,
                    f"must be finite and >= 0, got {value!r}",
                )

    @property
    def named(self) -> dict[str, Any]:
        """The criteria that are set, by name."""
        return {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if getattr(self, f.name) is not None
        }


#: The filter a scene runs behind unless its ``[filter]`` says otherwise: paper N's Eq. 18 plus
#: hazard memory, which keeps a pit whose rim drops out of the detection in the HDL-64's
#: ring-free disc while the car stands before it, and holds what it remembers within 8 m of the
#: rear axle, where closing in loses a pit's pairs while its floor still returns (docs/safety.md,
#: "Hazard memory"); the negobs envs hand the filter the pose and grid it needs. ``[filter]
#: hazard_memory = false`` gives paper N's stateless filter, the default of
#: :class:`SafetyFilterConfig` for any other env.
SCENE_FILTER = SafetyFilterConfig(hazard_memory=True, hazard_memory_hold_m=8.0)


@dataclass(frozen=True)
class SampledScenario:
    """One episode's draw of a spec: the terrain, the start pose and speed."""

    terrain: Terrain
    start_pose: Pose
    start_speed_mps: float


@dataclass(frozen=True, kw_only=True)
class ScenarioSpec:
    """A whole scenario (see the module docstring); build with :meth:`from_dict` or TOML."""

    name: str
    description: str = ""
    terrain: TerrainSpec
    obstacles: tuple[NegativeObstacleEntry, ...] = ()
    positive_obstacles: tuple[PositiveObstacleEntry, ...] = ()
    start: StartSpec = field(default_factory=StartSpec)
    episode: EpisodeSpec = field(default_factory=EpisodeSpec)
    task: TaskSpec = field(default_factory=TaskSpec)
    reward: RewardConfig = field(default_factory=RewardConfig)
    terminations: tuple[TerminationRule, ...] = (
        "entered_negative_obstacle",
        "trapped",
        "collision",
        "rollover",
        "goal",
    )
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    ins: InsSpec = field(default_factory=InsSpec)
    physics: EnvPhysicsConfig = field(default_factory=EnvPhysicsConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    run: RunSpec = field(default_factory=RunSpec)
    # how the safety filter decides when run.filter (or a command) puts it in: Eq. 18's mode, the
    # governor and hazard memory (docs/safety.md); SCENE_FILTER unless the spec says otherwise
    filter: SafetyFilterConfig = field(default_factory=lambda: SCENE_FILTER)
    criteria: CriteriaSpec = field(default_factory=CriteriaSpec)

    def __post_init__(self) -> None:
        require(isinstance(self.name, str) and self.name.strip() != "", "name", "must be a non-empty string")
        require(
            not (self.terrain.preset is not None and (self.obstacles or self.positive_obstacles)),
            "obstacles",
            f"preset {self.terrain.preset!r} places its own obstacles; use a course to list them",
        )
        require(
            len(set(self.terminations)) == len(self.terminations),
            "terminations",
            f"must not repeat a rule, got {list(self.terminations)}",
        )

    # -- plain data ----------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScenarioSpec:
        """Build and validate from plain data; a bad or unknown field raises ConfigError naming it.

        ``run.filter_mode`` and ``run.stop_for_positive`` are read as ``filter.mode`` and
        ``filter.stop_for_positive`` for one release, with a DeprecationWarning."""
        return from_plain(cls, _filter_over_scene_defaults(_moved_filter_keys(data)))

    def to_dict(self) -> dict[str, Any]:
        """Plain data that :meth:`from_dict` turns back into an equal spec (TOML-ready)."""
        return to_plain(self)

    # -- one episode ---------------------------------------------------------------------------
    def sample(self, rng: np.random.Generator) -> SampledScenario:
        """Draw the ranges and build the terrain, all from ``rng`` (in a fixed order: terrain
        parameters or obstacles, then the terrain seed, then the start)."""
        terrain = self._terrain(rng)
        start = _draw_fields(self.start, StartSpec._NUMBERS, rng)
        xy, yaw = terrain.track.pose_at(start["station_m"], start["lateral_m"])
        pose = Pose(x=float(xy[0]), y=float(xy[1]), yaw=float(yaw) + math.radians(start["yaw_deg"]) + 0.0)
        return SampledScenario(terrain=terrain, start_pose=pose, start_speed_mps=start["speed_mps"])

    def _terrain(self, rng: np.random.Generator) -> Terrain:
        if self.terrain.preset is not None:
            params = {k: _draw(v, rng) if isinstance(v, Range) else v for k, v in self.terrain.params.items()}
            seed = int(rng.integers(0, 2**31 - 1))
            try:
                return PRESETS[self.terrain.preset](**params, seed=seed)
            except ConfigError as exc:
                raise ConfigError(f"terrain.params.{exc.field}", str(exc)[len(exc.field) + 2 :]) from None
        config = dataclasses.replace(
            self.terrain.course,
            negative_obstacles=tuple(o.sample(rng) for o in self.obstacles),
            positive_obstacles=tuple(o.sample(rng) for o in self.positive_obstacles),
        )
        seed = int(rng.integers(0, 2**31 - 1))
        try:
            return generate_terrain(config, seed)
        except ConfigError as exc:  # e.g. an obstacle off the terrain: name it as the spec does
            name = exc.field.replace("negative_obstacles", "obstacles", 1)
            name = name if name.startswith(("obstacles", "positive_obstacles")) else f"terrain.course.{name}"
            raise ConfigError(name, str(exc)[len(exc.field) + 2 :]) from None


#: Keys of ``[run]`` that moved into ``[filter]`` (old name -> new name), read for one release.
MOVED_RUN_KEYS: Mapping[str, str] = {"filter_mode": "mode", "stop_for_positive": "stop_for_positive"}


def _moved_filter_keys(data: Mapping[str, Any]) -> Mapping[str, Any]:
    """``data`` with the old ``run`` keys of the filter moved to ``filter`` (warns once per key)."""
    run = data.get("run")
    if not isinstance(run, Mapping) or not set(run) & set(MOVED_RUN_KEYS):
        return data
    data, run = dict(data), dict(run)
    filter_table = data.get("filter", {})
    filter_table = dict(filter_table) if isinstance(filter_table, Mapping) else filter_table
    for old, new in MOVED_RUN_KEYS.items():
        if old in run:
            warnings.warn(
                f"run.{old} is now filter.{new} (the [filter] table); the old key goes in the next release",
                DeprecationWarning,
                stacklevel=4,
            )
            if isinstance(filter_table, dict):
                filter_table[new] = run[old]
            del run[old]
    data["run"], data["filter"] = run, filter_table
    return data


def _filter_over_scene_defaults(data: Mapping[str, Any]) -> Mapping[str, Any]:
    """``data`` with its ``[filter]`` settings laid over :data:`SCENE_FILTER`'s, so that a table
    naming only ``mode`` keeps the scene default's hazard memory."""
    given = data.get("filter")
    if not isinstance(given, Mapping) or isinstance(given, SafetyFilterConfig):
        return data
    merged = to_plain(SCENE_FILTER)
    for key, value in given.items():
        if key == "braking" and isinstance(value, Mapping):
            merged["braking"] = {**merged["braking"], **value}
        else:
            merged[key] = value
    return {**data, "filter": merged}


def spec_from_toml(text: str) -> ScenarioSpec:
    """Parse a TOML document into a validated :class:`ScenarioSpec`."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("toml", str(exc)) from None
    return ScenarioSpec.from_dict(data)


def spec_to_toml(spec: ScenarioSpec) -> str:
    """The spec as a TOML document that :func:`spec_from_toml` reads back into an equal spec."""
    return dumps_toml(spec.to_dict())
