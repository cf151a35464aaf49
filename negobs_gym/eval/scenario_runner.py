"""Scripted scenario runs: one episode of a spec with a scripted driver, a frozen result to assert on.

>>> result = run_scenario("braking_v1", "reckless", filter=True, seed=0)
>>> result.stopped_before, result.stop_margin_m, result.failures
"""

from __future__ import annotations

import contextlib
import multiprocessing
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.drivers import DRIVER_NAMES, Driver, ModelDriver
from negobs_gym.drivers import make_driver as make_named_driver
from negobs_gym.envs.base import NegObsEnv
from negobs_gym.errors import ConfigError
from negobs_gym.eval.episode import DriverSource, EpisodeResult, check_criteria, drive_episode
from negobs_gym.safety.filter import SafetyFilterConfig
from negobs_gym.sim.render import render_drive
from negobs_gym.sim.types import Terrain
from negobs_gym.spec.library import load_scenario
from negobs_gym.spec.scenario import ScenarioSpec

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


#: A scripted run's result: the one episode loop's (:class:`~negobs_gym.eval.episode.EpisodeResult`).
ScenarioResult = EpisodeResult


def make_driver(name: str, spec: ScenarioSpec, terrain: Terrain) -> Driver:
    """The scripted driver ``name`` at the spec's target speed and lane offset, with its
    ``run.driver_settings`` (:func:`negobs_gym.drivers.make_driver`).

    Raises:
        ConfigError: as :func:`negobs_gym.drivers.make_driver`; a bad driver setting names
            ``run.driver_settings``.
    """
    try:
        return make_named_driver(
            name,
            terrain,
            target_speed_mps=spec.run.target_speed_mps,
            lane_offset_m=spec.run.lane_offset_m,
            observation=spec.observation,
            settings=spec.run.driver_settings,
            safety_filter=spec.filter,
            control_period_s=1.0 / spec.episode.control_hz,
        )
    except ConfigError as exc:
        if exc.field != "driver_settings":
            raise
        raise ConfigError("run.driver_settings", exc.message) from None


def _pilot(spec: ScenarioSpec, driver: Driver | str | None) -> tuple[DriverSource, str]:
    """An episode's driver and its name in the result: ``driver`` (an object, or a scripted
    driver's name, built on the course the seed draws), else the spec's ``run.policy`` when it
    names one, else its ``run.driver``."""
    if driver is not None and not isinstance(driver, str):
        return driver, str(getattr(driver, "name", type(driver).__name__))
    if driver is None and spec.run.policy:
        return ModelDriver(spec.run.policy, spec.run.policy_algo), spec.run.policy
    name = driver or spec.run.driver
    return (lambda env: make_driver(name, spec, env.terrain)), name


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
        filter: True (the spec's ``[filter]`` settings: Eq. 18's defaults unless it sets them),
            a :class:`SafetyFilterConfig` (used as it is),
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
    pilot, name = _pilot(spec, driver)
    with contextlib.closing(NegObsEnv(scenario=spec, render_mode=render_mode)) as env:
        result = drive_episode(env, pilot, seed=seed, filter=filter, video_to=video_to, driver_name=name)
        if draw_to is not None:
            _draw(result, env.terrain, Path(draw_to), draw_zoom_m)
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
    # spawn: no inherited PyBullet/Embree state, as the campaigns' processes
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(seeds)), mp_context=context) as pool:
        futures = [pool.submit(run_scenario, spec, driver, **kwargs(seed)) for seed in seeds]
        for future in futures:  # in seed order: a later seed that finished first waits its turn
            yield future.result()


def _draw(result: ScenarioResult, terrain: Terrain, out_path: Path, zoom_m: float | None) -> None:
    """The drive from above (:func:`~negobs_gym.sim.render.render_drive`), captioned with its verdict."""
    verdict = "PASS" if result.passed else "FAIL " + ",".join(result.failures)
    filtered = "filter" if result.filtered else "no filter"
    caption = f"{result.scenario} seed {result.seed} {result.driver}, {filtered}: {verdict}"
    vetoed, missed = np.zeros((2, len(result.path_xy_m)), dtype=bool)
    vetoed[list(result.vetoed_steps)] = True
    missed[list(result.missed_steps)] = True
    xy, yaw = np.asarray(result.path_xy_m), result.path[-1].yaw_rad
    render_drive(terrain, xy, yaw, vetoed, caption, out_path, zoom_m, missed)
