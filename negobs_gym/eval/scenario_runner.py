"""Scripted scenario runs: one episode of a spec with a scripted driver, a frozen result to assert on.

>>> result = run_scenario("braking_v1", "reckless", filter=True, seed=0)
>>> result.stopped_before, result.stop_margin_m, result.failures
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from negobs_gym.drivers import DRIVER_NAMES, Driver
from negobs_gym.drivers import make_driver as make_named_driver
from negobs_gym.envs.base import NegObsEnv
from negobs_gym.envs.video import optional_video, recording
from negobs_gym.errors import ConfigError
from negobs_gym.eval.vetoes import VetoJudgement, VetoTally, format_veto_error
from negobs_gym.safety import BrakingSafetyFilter
from negobs_gym.safety.filter import SafetyFilterConfig
from negobs_gym.sim.types import Terrain
from negobs_gym.spec.library import load_scenario
from negobs_gym.spec.scenario import CriteriaSpec, RunSpec, ScenarioSpec

__all__ = [
    "DRIVERS",
    "ScenarioResult",
    "check_criteria",
    "make_driver",
    "run_scenario",
    "run_scenario_seeds",
]

#: Driver names a spec's ``run.driver`` or ``negobs scenario run --driver`` accepts.
DRIVERS: tuple[str, ...] = DRIVER_NAMES


@dataclass(frozen=True)
class ScenarioResult:
    """What one scripted episode did (ground truth; distances from the front bumper).

    Attributes:
        scenario: The spec's name.
        seed: Episode seed.
        driver: The scripted driver's name, the policy's (``run.policy``: a saved model's path or a
            shipped policy's name), or a driver object's ``name`` (else its class name).
        filtered: The safety filter guarded the driver.
        steps: Control steps run.
        time_s: Simulated time [s].
        entered_negative_obstacle: A wheel entered a negative obstacle.
        stopped_before: Standing at the end, never entered, a negative obstacle still ahead: in
            the wheels' strip straight ahead, or (behind the filter) along the corridor of its
            last decision, the arc of the steering the driver last proposed.
        stop_margin_m: Gap left to that obstacle when ``stopped_before``, else None [m]: the
            nearer of the two.
        start_gap_m: Gap to the nearest negative obstacle ahead at the start (inf: none) [m].
        collision: Touched a positive obstacle.
        trapped: Got stuck.
        rollover: Rolled or pitched past the limit.
        goal_reached: Reached the goal.
        left_track: The rear-axle centre left the track (beyond half its width) at some step.
        task_done: The spec's task succeeded: ``reach_goal`` = goal reached; ``stop_before_hazard``
            = ``stopped_before``; ``cross`` = goal reached without being trapped; ``follow`` = goal
            reached without leaving the track.
        max_decel_mps2: Largest speed drop over one control period, per second [m/s^2].
        vetoes: Steps whose action the filter replaced.
        false_vetoes: Vetoes with no true obstacle of the vetoing channel (negative, or positive
            with ``stop_for_positive``) within the filter's hazard distance plus
            :data:`~negobs_gym.eval.vetoes.FALSE_VETO_TOLERANCE_M`, along the corridor the filter
            searched (its proposed steering's arc, laid out from the pose where it decided;
            :func:`~negobs_gym.eval.vetoes.is_false_veto`).
        max_veto_error_m: The largest error of a veto's hazard distance: the distance the filter
            acted on minus the true one along its corridor
            (:func:`~negobs_gym.eval.vetoes.veto_error_m`); > 0: it saw the hazard that much
            farther than it was and braked later than the truth would have made it. None: no
            veto with a true obstacle along its corridor [m].
        positive_gap_m: Gap left at the end to the nearest positive obstacle ahead in the wheels'
            strip (inf: none) [m].
        termination: Termination rules that ended the episode (empty: truncated).
        truncated: Ended by the time limit.
        failures: Names of the spec's criteria this run failed (empty: passed).
        path_xy_m: The rear-axle centre's world position at the reset and after every step [m].
        vetoed_steps: The steps (1-based, indices into ``path_xy_m``) whose action the filter
            replaced.
        missed_steps: The steps (indices into ``path_xy_m``) the filter let through with a true
            hazard well inside R(v) (:attr:`missed_vetoes` counts them).
        veto_judgements: Each veto and missed veto in step order, with the speed, R(v), the
            distance the filter acted on, the true one and the actions
            (:class:`~negobs_gym.eval.vetoes.VetoJudgement`).
    """

    scenario: str
    seed: int
    driver: str
    filtered: bool
    steps: int
    time_s: float
    entered_negative_obstacle: bool
    stopped_before: bool
    stop_margin_m: float | None
    start_gap_m: float
    collision: bool
    trapped: bool
    rollover: bool
    goal_reached: bool
    left_track: bool
    task_done: bool
    max_decel_mps2: float
    vetoes: int
    false_vetoes: int
    max_veto_error_m: float | None
    positive_gap_m: float
    termination: tuple[str, ...]
    truncated: bool
    failures: tuple[str, ...] = ()
    path_xy_m: tuple[tuple[float, float], ...] = ()
    vetoed_steps: tuple[int, ...] = ()
    missed_steps: tuple[int, ...] = ()
    veto_judgements: tuple[VetoJudgement, ...] = ()

    @property
    def missed_vetoes(self) -> int:
        """Steps the filter let through while a true obstacle lay along its corridor more than
        :data:`~negobs_gym.eval.vetoes.FALSE_VETO_TOLERANCE_M` inside R(v) (negative; positive too
        with ``stop_for_positive``; :func:`~negobs_gym.eval.vetoes.is_missed_veto`): hazards the
        detectors did not report in time. 0 without the filter."""
        return len(self.missed_steps)

    @property
    def veto_events(self) -> int:
        """Braking events: runs of consecutive vetoed steps, each begun by an onset veto
        (:attr:`~negobs_gym.eval.vetoes.VetoJudgement.onset`; the braking campaign's ``veto_events``)."""
        return sum(j.onset for j in self.veto_judgements)

    @property
    def passed(self) -> bool:
        """Every criterion named in the spec held."""
        return not self.failures

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
            f"max_decel={self.max_decel_mps2:.2f} vetoes={self.vetoes} false_vetoes={self.false_vetoes} "
            f"missed_vetoes={self.missed_vetoes} veto_error_m={format_veto_error(self.max_veto_error_m)} "
            f"time_s={self.time_s:.1f} end={end} {verdict}"
        )


def check_criteria(criteria: CriteriaSpec, result: ScenarioResult) -> tuple[str, ...]:
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


def make_driver(name: str, spec: ScenarioSpec, terrain: Terrain) -> Driver:
    """The scripted driver ``name`` at the spec's target speed and lane offset
    (:func:`negobs_gym.drivers.make_driver`)."""
    return make_named_driver(
        name, terrain, target_speed_mps=spec.run.target_speed_mps, lane_offset_m=spec.run.lane_offset_m
    )


def _pilot(spec: ScenarioSpec, driver: Driver | str | None, terrain: Terrain) -> tuple[Driver, str]:
    """An episode's driver and its name in the result: ``driver`` (an object, or a scripted
    driver's name), else the spec's ``run.policy`` when it names one, else its ``run.driver``."""
    if driver is not None and not isinstance(driver, str):
        return driver, str(getattr(driver, "name", type(driver).__name__))
    if driver is None and spec.run.policy:
        from negobs_gym.drivers.model import ModelDriver

        return ModelDriver(spec.run.policy, spec.run.policy_algo), spec.run.policy
    name = driver or spec.run.driver
    return make_driver(name, spec, terrain), name


def _guard(filter: bool | SafetyFilterConfig, run: RunSpec) -> SafetyFilterConfig | None:
    """The filter's settings (None: no filter); True takes the spec's ``run.stop_for_positive``."""
    if filter is False:
        return None
    if not isinstance(filter, SafetyFilterConfig):
        filter = SafetyFilterConfig(stop_for_positive=run.stop_for_positive)
    return filter


def run_scenario(
    spec: ScenarioSpec | str | Path,
    driver: Driver | str | None = None,
    *,
    filter: bool | SafetyFilterConfig | None = None,
    seed: int = 0,
    render_mode: str | None = None,
    draw_to: str | Path | None = None,
    draw_zoom_m: float | None = None,
    video_to: str | Path | None = None,
) -> ScenarioResult:
    """Run one episode of ``spec`` (a spec, shipped name or TOML path) with a scripted driver.

    Args:
        spec: The scenario.
        driver: A driver name (:data:`DRIVERS`), a :class:`~negobs_gym.drivers.Driver` (e.g. a
            trained model, :class:`~negobs_gym.drivers.model.ModelDriver`), or None for
            the spec's ``run.policy`` when it names one, else its ``run.driver``.
        filter: True (the Eq. 18 defaults, stopping for positive obstacles when the spec's
            ``run.stop_for_positive`` says so), a :class:`SafetyFilterConfig` (used as it is),
            False, or None for the spec's ``run.filter``.
        seed: Episode seed (terrain draws, sensor noise, the driver's ``reset``).
        render_mode: Passed to the env (e.g. to keep frames for a failing test).
        draw_to: A PNG to write at the end (atomically): the terrain from above with the path, the
            car where it ended, the vetoed steps, the missed vetoes and the result's verdict.
        draw_zoom_m: Draw only the square of this half-width around where the car ended (1000 px
            a side, to see how it ended); None: the whole terrain.
        video_to: An MP4 to write (atomically, at the end): the env's ``rgb_array`` frame after
            the reset and after every step, in real time (the control rate), the filter's corridor
            and decision drawn in each (:class:`~negobs_gym.envs.video.EpisodeVideo`; needs the
            ``video`` extra). The episode is the same with or without it.

    Returns:
        The episode's :class:`ScenarioResult`, with the spec's failed criteria in ``failures``.
    """
    spec = load_scenario(spec)
    if draw_zoom_m is not None and not (np.isfinite(draw_zoom_m) and draw_zoom_m > 0):
        raise ConfigError("draw_zoom_m", f"must be finite and > 0, got {draw_zoom_m!r}")
    if video_to is not None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError("render_mode", f"video_to needs 'rgb_array' frames, got {render_mode!r}")
        render_mode = "rgb_array"
    filter = spec.run.filter if filter is None else filter
    base = NegObsEnv(scenario=spec, render_mode=render_mode)
    guard = _guard(filter, spec.run)
    env = base if guard is None else BrakingSafetyFilter(base, config=guard)
    with contextlib.closing(env), optional_video(video_to, fps=base.config.control_hz) as video:
        return _run_episode(spec, driver, recording(env, video), base, guard, seed, draw_to, draw_zoom_m)


def _run_episode(
    spec: ScenarioSpec,
    driver: Driver | str | None,
    env: gym.Env,
    base: NegObsEnv,
    guard: SafetyFilterConfig | None,
    seed: int,
    draw_to: str | Path | None,
    draw_zoom_m: float | None,
) -> ScenarioResult:
    """The episode of :func:`run_scenario` in ``env`` (``base`` unwrapped; behind the filter
    ``guard`` unless None)."""
    obs, info = env.reset(seed=seed)
    pilot, name = _pilot(spec, driver, base.terrain)
    pilot.reset(seed)
    dt = 1.0 / base.config.control_hz
    start_gap = float(info["distance_to_negative_ahead_m"])
    entered = collision = trapped = rollover = goal = left = False
    steps = 0
    tally = VetoTally(positive=guard is not None and guard.stop_for_positive)
    max_decel = 0.0
    terminated = truncated = False
    path = [_xy(info)]
    while not (terminated or truncated):
        before = info
        speed_before = info["speed_mps"]
        obs, _, terminated, truncated, info = env.step(pilot.act(obs, info))
        steps += 1
        path.append(_xy(info))
        tally.add(base, info.get("safety"), before, steps)
        max_decel = max(max_decel, (speed_before - info["speed_mps"]) / dt)
        ev = info["events"]
        entered |= bool(ev["entered_negative_obstacle"])
        collision |= bool(ev["collision"])
        trapped |= bool(ev["trapped"])
        rollover |= bool(ev["rollover"])
        goal |= bool(info["goal_reached"])
        left |= bool(info["off_track"])
    gap = _stop_gap_m(base, info)
    stopped = not entered and abs(info["speed_mps"]) < spec.task.stop_speed_mps and np.isfinite(gap)
    task_done = {
        "reach_goal": goal,
        "stop_before_hazard": stopped,
        "cross": goal and not trapped,
        "follow": goal and not left,
    }[spec.task.kind]
    result = ScenarioResult(
        scenario=spec.name,
        seed=seed,
        driver=name,
        filtered=guard is not None,
        steps=steps,
        time_s=steps * dt,
        entered_negative_obstacle=entered,
        stopped_before=bool(stopped),
        stop_margin_m=gap if stopped else None,
        start_gap_m=start_gap,
        collision=collision,
        trapped=trapped,
        rollover=rollover,
        goal_reached=goal,
        left_track=left,
        task_done=bool(task_done),
        max_decel_mps2=float(max_decel),
        vetoes=len(tally.vetoed_steps),
        false_vetoes=tally.false_vetoes,
        max_veto_error_m=tally.max_error_m,
        positive_gap_m=float(info["distance_to_positive_ahead_m"]),
        termination=tuple(info["termination"]),
        truncated=bool(truncated and not terminated),
        path_xy_m=tuple(path),
        vetoed_steps=tuple(tally.vetoed_steps),
        missed_steps=tuple(tally.missed_steps),
        veto_judgements=tuple(tally.judgements),
    )
    result = dataclasses.replace(result, failures=check_criteria(spec.criteria, result))
    if draw_to is not None:
        _draw(result, base.terrain, float(info["pose"][5]), Path(draw_to), draw_zoom_m)
    return result


def run_scenario_seeds(
    spec: ScenarioSpec | str | Path,
    driver: Driver | str | None = None,
    seeds: Sequence[int] = (0,),
    *,
    filter: bool | SafetyFilterConfig | None = None,
    workers: int = 1,
    draw_dir: str | Path | None = None,
    draw_zoom_m: float | None = None,
    video_dir: str | Path | None = None,
) -> Iterator[ScenarioResult]:
    """:func:`run_scenario` once per seed, in ``workers`` processes; results yielded in seed order.

    Each seed's episode is the same whatever the worker count (it depends on the seed alone).
    ``driver`` is a name, None, or a driver that pickles (a
    :class:`~negobs_gym.drivers.model.ModelDriver` pickles as its model's path) when
    ``workers`` > 1.
    ``draw_dir``: each seed's drive as ``<draw_dir>/<scenario>_seed<k>.png``; ``video_dir``: each
    seed's episode as ``<video_dir>/<scenario>_seed<k>.mp4`` (``video_to`` of :func:`run_scenario`).

    Raises:
        ConfigError: ``workers`` < 1 (when called, not at the first result).
    """
    spec = load_scenario(spec)
    if not (isinstance(workers, int) and workers >= 1):
        raise ConfigError("workers", f"must be an int >= 1, got {workers!r}")
    outputs = {"draw_dir": draw_dir, "draw_zoom_m": draw_zoom_m, "video_dir": video_dir}
    return _seed_results(spec, driver, list(seeds), filter, workers, **outputs)


def _seed_results(
    spec: ScenarioSpec,
    driver: Driver | str | None,
    seeds: list[int],
    filter: bool | SafetyFilterConfig | None,
    workers: int,
    draw_dir: str | Path | None,
    draw_zoom_m: float | None,
    video_dir: str | Path | None,
) -> Iterator[ScenarioResult]:
    """The results of :func:`run_scenario_seeds`, run as they are asked for."""

    def in_dir(folder: str | Path | None, seed: int, suffix: str) -> Path | None:
        return Path(folder) / f"{spec.name}_seed{seed}{suffix}" if folder is not None else None

    def kwargs(seed: int) -> dict[str, Any]:
        return {
            "filter": filter,
            "seed": seed,
            "draw_to": in_dir(draw_dir, seed, ".png"),
            "draw_zoom_m": draw_zoom_m,
            "video_to": in_dir(video_dir, seed, ".mp4"),
        }

    if workers == 1 or len(seeds) < 2:
        for seed in seeds:
            yield run_scenario(spec, driver, **kwargs(seed))
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    # spawn: no inherited PyBullet/Embree state, as the campaigns' processes
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(seeds)), mp_context=context) as pool:
        futures = [pool.submit(run_scenario, spec, driver, **kwargs(seed)) for seed in seeds]
        for future in futures:  # in seed order: a later seed that finished first waits its turn
            yield future.result()


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


def _xy(info: dict[str, Any]) -> tuple[float, float]:
    return float(info["pose"][0]), float(info["pose"][1])


def _draw(
    result: ScenarioResult, terrain: Terrain, yaw_rad: float, out_path: Path, zoom_m: float | None
) -> None:
    from negobs_gym.sim.render import render_drive

    verdict = "PASS" if result.passed else "FAIL " + ",".join(result.failures)
    filtered = "filter" if result.filtered else "no filter"
    caption = f"{result.scenario} seed {result.seed} {result.driver}, {filtered}: {verdict}"
    vetoed, missed = np.zeros((2, len(result.path_xy_m)), dtype=bool)
    vetoed[list(result.vetoed_steps)] = True
    missed[list(result.missed_steps)] = True
    render_drive(terrain, np.asarray(result.path_xy_m), yaw_rad, vetoed, caption, out_path, zoom_m, missed)
