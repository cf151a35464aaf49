"""The one episode loop: a driver or a policy on an env, behind the Eq. 18 filter or not, measured.

Scenario runs (:mod:`~negobs_gym.eval.scenario_runner`), the braking and policy campaigns,
training's evaluation and the quick-start demo all drive their episodes with :func:`drive_episode`,
so a measure means the same wherever it is reported.

>>> from negobs_gym.drivers import RecklessDriver
>>> from negobs_gym.envs import make_env
>>> env = make_env("braking_v1")
>>> result = drive_episode(env, RecklessDriver(), seed=0, filter=True)
>>> env.close()
>>> result.stopped_before, result.stop_margin_m, result.vetoes
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from negobs_gym.drivers import Driver
from negobs_gym.envs.base import NegObsEnv
from negobs_gym.envs.video import optional_video, recording
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.vetoes import VetoJudgement, VetoTally, format_veto_error, largest_veto_error_m
from negobs_gym.safety.filter import BrakingSafetyFilter, SafetyFilterConfig
from negobs_gym.spec.scenario import CriteriaSpec, ScenarioSpec

__all__ = [
    "STANDSTILL_S",
    "DriverSource",
    "EpisodeResult",
    "EpisodeStop",
    "PathPoint",
    "check_criteria",
    "drive_episode",
    "filter_settings",
]

#: How long standing still ends the episodes of the campaigns, the demo and training's evaluation
#: (a stop the car holds for a second is a stop; engineering choice) [s]
STANDSTILL_S = 1.0

#: A driver (``reset(seed)``, ``act(obs, info)``), or a function that builds one from the env
#: after its reset (scripted drivers that follow the course need the terrain the seed drew).
DriverSource = Driver | Callable[[NegObsEnv], Driver]


@dataclass(frozen=True, kw_only=True)
class EpisodeStop:
    """When the loop ends an episode besides the env's own termination and truncation.

    Attributes:
        max_steps: The most control steps (None: only the env's own limits).
        standstill_s: End once the car has stood still this long [s] (None: never; the
            campaigns use :data:`STANDSTILL_S`).
        standstill_mps: Below this speed the car stands still [m/s].
    """

    max_steps: int | None = None
    standstill_s: float | None = None
    standstill_mps: float = 0.1  # a car creeping slower than this has stopped (engineering choice)

    def __post_init__(self) -> None:
        require(
            self.max_steps is None or (type(self.max_steps) is int and self.max_steps >= 1),
            "max_steps",
            f"must be None or an int >= 1, got {self.max_steps!r}",
        )
        require(
            self.standstill_s is None or (math.isfinite(self.standstill_s) and self.standstill_s > 0),
            "standstill_s",
            f"must be None or finite and > 0, got {self.standstill_s!r}",
        )
        require(
            math.isfinite(self.standstill_mps) and self.standstill_mps > 0,
            "standstill_mps",
            f"must be finite and > 0, got {self.standstill_mps!r}",
        )


class PathPoint(NamedTuple):
    """The car at the reset or after a step: rear-axle centre in world metres, yaw, forward speed."""

    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float


@dataclass(frozen=True, kw_only=True)
class EpisodeResult:
    """What one episode did (ground truth; distances from the front bumper).

    Attributes:
        scenario: The spec's name.
        seed: Episode seed.
        driver: The driver's name (``drive_episode``'s ``driver_name``, else the driver's ``name``,
            else its class name).
        filtered: The safety filter guarded the driver.
        steps: Control steps run.
        time_s: Simulated time [s].
        distance_m: Path length the rear-axle centre drove [m].
        progress_m: Station gained along the track [m].
        entered_negative_obstacle: A wheel entered a negative obstacle.
        collision: Touched a positive obstacle.
        trapped: Got stuck.
        rollover: Rolled or pitched past the limit.
        goal_reached: Reached the goal.
        off_track_steps: Steps that ended with the rear-axle centre off the track (farther from
            the centre line than half the track width).
        stopped: The loop ended it standing still for :attr:`EpisodeStop.standstill_s` (False
            without that rule).
        stopped_before: Standing at the end (below the spec's ``task.stop_speed_mps``), never
            entered, a negative obstacle still ahead: in the wheels' strip straight ahead, or
            (behind the filter) along the corridor of its last decision, the arc of the steering
            the driver last proposed.
        stop_margin_m: Gap left to that obstacle when ``stopped_before``, else None [m]: the
            nearer of the two.
        task_done: The spec's task succeeded: ``reach_goal`` = goal reached; ``stop_before_hazard``
            = ``stopped_before``; ``cross`` = goal reached without being trapped; ``follow`` = goal
            reached without leaving the track.
        start_gap_m: Gap to the nearest negative obstacle ahead at the start (inf: none) [m].
        final_gap_m: The same at the end, straight ahead in the wheels' strip [m].
        first_veto_gap_m: The same before the first vetoed step (None: no veto) [m].
        positive_gap_m: Gap left at the end to the nearest positive obstacle ahead in the wheels'
            strip (inf: none) [m].
        final_speed_mps: Forward speed at the end [m/s].
        max_decel_mps2: Largest speed drop over one control period, per second [m/s^2].
        cost: The summed constraint cost (``info["cost"]``).
        termination: Termination rules that ended the episode (empty: truncated, or ended by the
            loop's :class:`EpisodeStop`).
        truncated: Ended by the env's time limit.
        failures: Names of the spec's criteria this run failed (empty: passed).
        steered_steps: Steps whose steering the filter changed ahead of a veto (its
            ``steer_search``; 0 without it).
        path: The car at the reset and after every step (:class:`PathPoint`).
        veto_judgements: Each veto and missed veto in step order, with the speed, R(v), the
            distance the filter acted on, the true one and the actions
            (:class:`~negobs_gym.eval.vetoes.VetoJudgement`). A veto is *false* with no true
            obstacle of the vetoing channel within the filter's hazard distance plus
            :data:`~negobs_gym.eval.vetoes.FALSE_VETO_TOLERANCE_M` along the corridor it searched;
            a *missed veto* is a step let through with a true hazard well inside R(v)
            (:mod:`negobs_gym.eval.vetoes`).
    """

    scenario: str
    seed: int
    driver: str
    filtered: bool
    steps: int
    time_s: float
    distance_m: float
    progress_m: float
    entered_negative_obstacle: bool
    collision: bool
    trapped: bool
    rollover: bool
    goal_reached: bool
    off_track_steps: int
    stopped: bool
    stopped_before: bool
    stop_margin_m: float | None
    task_done: bool
    start_gap_m: float
    final_gap_m: float
    first_veto_gap_m: float | None
    positive_gap_m: float
    final_speed_mps: float
    max_decel_mps2: float
    cost: float
    termination: tuple[str, ...]
    truncated: bool
    failures: tuple[str, ...] = ()
    steered_steps: int = 0
    path: tuple[PathPoint, ...] = ()
    veto_judgements: tuple[VetoJudgement, ...] = ()

    @property
    def left_track(self) -> bool:
        """The rear-axle centre left the track (beyond half its width) at some step."""
        return self.off_track_steps > 0

    @property
    def ended_off_track(self) -> bool:
        """Leaving the track ended the episode (the env's ``off_track`` rule, OffroadNav-v2)."""
        return "off_track" in self.termination

    @property
    def path_xy_m(self) -> tuple[tuple[float, float], ...]:
        """The rear-axle centre's world position at the reset and after every step [m]."""
        return tuple((p.x_m, p.y_m) for p in self.path)

    @property
    def vetoed_steps(self) -> tuple[int, ...]:
        """The steps (1-based, indices into :attr:`path`) whose action the filter replaced."""
        return tuple(j.step for j in self.veto_judgements if j.vetoed)

    @property
    def missed_steps(self) -> tuple[int, ...]:
        """The steps (indices into :attr:`path`) the filter let through with a true hazard well
        inside R(v)."""
        return tuple(j.step for j in self.veto_judgements if not j.vetoed)

    @property
    def vetoes(self) -> int:
        """Steps whose action the filter replaced."""
        return len(self.vetoed_steps)

    @property
    def false_vetoes(self) -> int:
        """Vetoes with no true obstacle where the filter saw its hazard
        (:func:`~negobs_gym.eval.vetoes.is_false_veto`)."""
        return sum(j.false_veto for j in self.veto_judgements)

    @property
    def missed_vetoes(self) -> int:
        """Steps the filter let through while a true obstacle lay along its corridor well inside
        R(v) (:func:`~negobs_gym.eval.vetoes.is_missed_veto`): hazards the detectors did not
        report in time. 0 without the filter."""
        return len(self.missed_steps)

    @property
    def veto_events(self) -> int:
        """Braking events: runs of consecutive vetoed steps, each begun by an onset veto
        (:attr:`~negobs_gym.eval.vetoes.VetoJudgement.onset`)."""
        return sum(j.onset for j in self.veto_judgements)

    @property
    def max_veto_error_m(self) -> float | None:
        """The largest error of a veto's hazard distance: the distance the filter acted on minus
        the true one along its corridor (:func:`~negobs_gym.eval.vetoes.veto_error_m`); > 0: it
        saw the hazard that much farther than it was. None: no veto with a true obstacle along
        its corridor [m]."""
        return largest_veto_error_m(j.error_m for j in self.veto_judgements)

    @property
    def passed(self) -> bool:
        """Every criterion named in the spec held."""
        return not self.failures

    def metrics(self) -> dict[str, Any]:
        """The campaigns' per-episode measures by their column names (NaN where the result holds
        None); what training's evaluation returns per episode."""

        def nan_if_none(value: float | None) -> float:  # a CSV cell takes NaN
            return math.nan if value is None else value

        return {
            "steps": self.steps,
            "distance_m": self.distance_m,
            "progress_m": self.progress_m,
            "entered": self.entered_negative_obstacle,
            "collision": self.collision,
            "rollover": self.rollover,
            "trapped": self.trapped,
            "goal": self.goal_reached,
            "off_track_steps": self.off_track_steps,
            "left_track": self.ended_off_track,
            "stopped": self.stopped,
            "start_gap_m": self.start_gap_m,
            "final_gap_m": self.final_gap_m,
            "first_veto_gap_m": nan_if_none(self.first_veto_gap_m),
            "vetoes": self.vetoes,
            "veto_events": self.veto_events,
            "false_vetoes": self.false_vetoes,
            "missed_vetoes": self.missed_vetoes,
            "max_veto_error_m": nan_if_none(self.max_veto_error_m),
            "cost": self.cost,
            "steered_steps": self.steered_steps,
        }

    def line(self) -> str:
        """One-line summary (what ``negobs scenario run`` prints per seed)."""
        margin = f"{self.stop_margin_m:.2f}" if self.stop_margin_m is not None else "-"
        positive_gap = f"{self.positive_gap_m:.2f}" if math.isfinite(self.positive_gap_m) else "-"
        end = ",".join(self.termination) or ("time_limit" if self.truncated else "-")
        verdict = "PASS" if self.passed else "FAIL " + ",".join(self.failures)
        filtered = "on" if self.filtered else "off"
        return (
            f"{self.scenario} seed={self.seed} driver={self.driver} filter={filtered} "
            f"task_done={int(self.task_done)} "
            f"entered={int(self.entered_negative_obstacle)} stopped_before={int(self.stopped_before)} "
            f"margin_m={margin} collision={int(self.collision)} positive_gap_m={positive_gap} "
            f"goal={int(self.goal_reached)} "
            f"max_decel={self.max_decel_mps2:.2f} vetoes={self.vetoes} steered={self.steered_steps} "
            f"false_vetoes={self.false_vetoes} "
            f"missed_vetoes={self.missed_vetoes} veto_error_m={format_veto_error(self.max_veto_error_m)} "
            f"time_s={self.time_s:.1f} end={end} {verdict}"
        )


def check_criteria(criteria: CriteriaSpec, result: EpisodeResult) -> tuple[str, ...]:
    """Names of the criteria that ``result`` fails (unset criteria are skipped)."""
    margin = result.stop_margin_m
    checks = {
        "task_done": lambda v: result.task_done == v,
        "entered_negative_obstacle": lambda v: result.entered_negative_obstacle == v,
        "stopped_before": lambda v: result.stopped_before == v,
        "min_stop_margin_m": lambda v: margin is not None and margin >= v,
        "max_stop_margin_m": lambda v: margin is not None and margin <= v,
        "min_positive_gap_m": lambda v: result.positive_gap_m >= v,
        "collision": lambda v: result.collision == v,
        "goal_reached": lambda v: result.goal_reached == v,
        "left_track": lambda v: result.left_track == v,
        "max_decel_mps2": lambda v: result.max_decel_mps2 <= v,
        "max_vetoes": lambda v: result.vetoes <= v,
        "max_false_vetoes": lambda v: result.false_vetoes <= v,
        "max_missed_vetoes": lambda v: result.missed_vetoes <= v,
        "max_veto_error_m": lambda v: result.max_veto_error_m is None or result.max_veto_error_m <= v,
        "max_time_s": lambda v: result.time_s <= v,
    }
    return tuple(name for name, value in criteria.named.items() if not checks[name](value))


def filter_settings(
    filter: bool | SafetyFilterConfig | None, spec: ScenarioSpec
) -> SafetyFilterConfig | None:
    """The filter an episode runs behind (None: none). A :class:`SafetyFilterConfig` as it is; a
    true flag the spec's ``[filter]`` settings; None the spec's ``run.filter``."""
    if filter is None:
        filter = spec.run.filter
    if isinstance(filter, SafetyFilterConfig):
        return filter
    return spec.filter if filter else None


def drive_episode(
    env: gym.Env,
    driver: DriverSource,
    *,
    seed: int,
    filter: bool | SafetyFilterConfig | None = None,
    stop: EpisodeStop = EpisodeStop(),
    video_to: str | Path | None = None,
    driver_name: str | None = None,
) -> EpisodeResult:
    """Drive one episode of ``env`` (a negobs env, wrapped or not) from ``seed``; what it did.

    Args:
        env: The env; it stays open (the caller closes it) and is wrapped in the filter here.
        driver: A driver, or a function of the reset env that builds one (:data:`DriverSource`);
            reset with ``seed`` after the env.
        seed: Episode seed (terrain draws, sensor noise, the driver's ``reset``).
        filter: The Eq. 18 braking safety filter (:func:`filter_settings`: a
            :class:`SafetyFilterConfig`, True, False, or None for the spec's ``run.filter``).
        stop: Ends besides the env's own (:class:`EpisodeStop`).
        video_to: An MP4 to write (atomically, at the end): the env's ``rgb_array`` frame after
            the reset and after every step at the control rate, the filter's corridor and decision
            drawn in each (:class:`~negobs_gym.envs.video.EpisodeVideo`; needs the ``video``
            extra). The episode is the same with or without it.
        driver_name: How the result names the driver (default: its ``name``, else its class).

    Raises:
        ConfigError: ``video_to`` on an env that does not render ``rgb_array`` frames.
    """
    base = env.unwrapped
    spec: ScenarioSpec = base.scenario
    if video_to is not None and env.render_mode != "rgb_array":
        raise ConfigError("video_to", f"needs an env rendering 'rgb_array' frames, got {env.render_mode!r}")
    guard = filter_settings(filter, spec)
    if guard is not None:
        env = BrakingSafetyFilter(env, config=guard)
    with optional_video(video_to, fps=spec.episode.control_hz) as video:
        return _drive(recording(env, video), base, spec, driver, seed, guard, stop, driver_name)


def _drive(
    env: gym.Env,
    base: NegObsEnv,
    spec: ScenarioSpec,
    driver: DriverSource,
    seed: int,
    guard: SafetyFilterConfig | None,
    stop: EpisodeStop,
    driver_name: str | None,
) -> EpisodeResult:
    """The episode of :func:`drive_episode` in ``env`` (filter and recorder applied)."""
    obs, info = env.reset(seed=seed)
    pilot = driver if hasattr(driver, "act") else driver(base)
    pilot.reset(seed)
    dt = 1.0 / spec.episode.control_hz
    start_gap, start_station = float(info["distance_to_negative_ahead_m"]), float(info["station_m"])
    events = {"entered_negative_obstacle": False, "collision": False, "rollover": False, "trapped": False}
    tally = VetoTally(positive=guard is not None and guard.stop_for_positive)
    first_veto: float | None = None
    goal, steps, off_track_steps, distance, cost, max_decel, still_s = False, 0, 0, 0.0, 0.0, 0.0, 0.0
    steered = 0
    terminated = truncated = standstill = False
    last_xy = np.asarray(info["pose"][:2], dtype=np.float64)
    path = [_point(info)]
    while not (terminated or truncated or standstill) and (stop.max_steps is None or steps < stop.max_steps):
        before, gap, speed_before = info, float(info["distance_to_negative_ahead_m"]), info["speed_mps"]
        obs, _, terminated, truncated, info = env.step(pilot.act(obs, info))
        steps += 1
        xy = np.asarray(info["pose"][:2], dtype=np.float64)
        distance += float(np.hypot(*(xy - last_xy)))
        last_xy = xy
        for k in events:
            events[k] |= bool(info["events"][k])
        goal |= bool(info.get("goal_reached", False))
        off_track_steps += bool(info.get("off_track", False))
        vetoed, _ = tally.add(base, info.get("safety"), before, steps)
        if vetoed and first_veto is None:
            first_veto = gap
        path.append(_point(info))
        cost += float(info.get("cost", 0.0))
        steered += bool((info.get("safety") or {}).get("steered", False))
        max_decel = max(max_decel, (speed_before - info["speed_mps"]) / dt)
        still_s = still_s + dt if info["speed_mps"] < stop.standstill_mps else 0.0
        standstill = stop.standstill_s is not None and still_s >= stop.standstill_s
    entered = events["entered_negative_obstacle"]
    gap = _stop_gap_m(base, info)
    stopped_before = bool(
        not entered and abs(info["speed_mps"]) < spec.task.stop_speed_mps and np.isfinite(gap)
    )
    task_done = {
        "reach_goal": goal,
        "stop_before_hazard": stopped_before,
        "cross": goal and not events["trapped"],
        "follow": goal and not off_track_steps,
    }[spec.task.kind]
    result = EpisodeResult(
        scenario=spec.name,
        seed=seed,
        driver=driver_name or str(getattr(pilot, "name", type(pilot).__name__)),
        filtered=guard is not None,
        steps=steps,
        time_s=steps * dt,
        distance_m=distance,
        progress_m=float(info["station_m"]) - start_station,
        entered_negative_obstacle=entered,
        collision=events["collision"],
        trapped=events["trapped"],
        rollover=events["rollover"],
        goal_reached=goal,
        off_track_steps=off_track_steps,
        stopped=standstill,
        stopped_before=stopped_before,
        stop_margin_m=gap if stopped_before else None,
        task_done=bool(task_done),
        start_gap_m=start_gap,
        final_gap_m=float(info["distance_to_negative_ahead_m"]),
        first_veto_gap_m=first_veto,
        positive_gap_m=float(info["distance_to_positive_ahead_m"]),
        final_speed_mps=float(info["speed_mps"]),
        max_decel_mps2=float(max_decel),
        cost=cost,
        steered_steps=steered,
        termination=tuple(info.get("termination", ())),
        truncated=bool(truncated and not terminated),
        path=tuple(path),
        veto_judgements=tuple(tally.judgements),
    )
    return dataclasses.replace(result, failures=check_criteria(spec.criteria, result))


def _stop_gap_m(base: NegObsEnv, info: dict[str, Any]) -> float:
    """Front bumper to the nearest true negative obstacle where the car is headed at the end (inf:
    none): straight ahead in the wheels' strip, or along the corridor of the filter's last decision
    (the steering the driver last proposed) when that is nearer."""
    gap = float(info["distance_to_negative_ahead_m"])
    record = info.get("safety")
    if record is None or record.get("corridor") is None:
        return gap
    corridor = record["corridor"]
    along = base.true_hazard_distance_m(corridor, info["pose"], "negative") - corridor.front_length_m
    return min(gap, along)


def _point(info: dict[str, Any]) -> PathPoint:
    x, y, _, _, _, yaw = (float(v) for v in info["pose"])
    return PathPoint(x, y, yaw, float(info["speed_mps"]))
