"""Braking campaign at 25 km/h: drivers with and without the Eq. 18 safety filter, per scenario.

Configurations are data: every scenario of :data:`SCENARIOS` (paper N's pit sizes, the Braking
ditch, a narrow trench, an off-centre pit, an obstacle-free track for false vetoes) x every driver
(scripted drivers of :mod:`negobs_gym.drivers`, optionally a saved SB3 model) x filter off / on
(:class:`~negobs_gym.safety.BrakingSafetyFilter`), each run on seeds 0..n-1. One CSV row per
episode (:data:`COLUMNS`), each episode's path in ``paths.csv`` (:data:`PATH_COLUMNS`, drawn by
``negobs eval paths``), and each veto and missed veto judged on the ground truth in ``vetoes.csv``
(:data:`VETO_COLUMNS`); :func:`summarize` turns the CSVs into per-configuration counts.

:func:`run_driven_episode` is also what ``negobs eval policy`` runs on a registered env id.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.drivers.model import ModelDriver
from negobs_gym.envs import NegObsEnv
from negobs_gym.envs.video import optional_video, recording
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.campaign import Episode, Rows, RunOptions, format_row, read_csv
from negobs_gym.eval.stats import format_interval, rate_interval
from negobs_gym.eval.vetoes import (
    VETO_COLUMNS,
    VetoTally,
    format_veto_error,
    largest_veto_error_m,
    veto_rows,
)
from negobs_gym.safety.filter import SafetyFilterConfig, filter_config
from negobs_gym.spec import RIGS, ObservationConfig, ScenarioSpec, load_scenario

STANDSTILL_MPS = 0.1  # below this speed for STANDSTILL_S the vehicle has stopped (as the demo)
STANDSTILL_S = 1.0

#: Scenarios as data: name -> (terrain preset of :mod:`negobs_gym.sim.presets`, its arguments).
#: Obstacle scenarios put the obstacle's near edge 20-40 m ahead (drawn per seed, as Braking-v0).
SCENARIOS: dict[str, tuple[str, dict[str, float]]] = {
    # Braking-v0's ditch: 1.0 m along the track, 3.0 m across, 0.8 m deep
    "ditch": ("braking_track", {"ditch_length_m": 1.0, "ditch_width_m": 3.0, "ditch_depth_m": 0.8}),
    # paper N §4.1's pit sizes, the long side across the track, 0.8 m deep
    "pit_100x50": ("braking_track", {"ditch_length_m": 0.5, "ditch_width_m": 1.0, "ditch_depth_m": 0.8}),
    "pit_100x80": ("braking_track", {"ditch_length_m": 0.8, "ditch_width_m": 1.0, "ditch_depth_m": 0.8}),
    "pit_150x60": ("braking_track", {"ditch_length_m": 0.6, "ditch_width_m": 1.5, "ditch_depth_m": 0.8}),
    "pit_100x100": ("braking_track", {"ditch_length_m": 1.0, "ditch_width_m": 1.0, "ditch_depth_m": 0.8}),
    # a narrow trench across the whole track: 0.4 m along it (paper N's 0.30 m minimum width + 10 cm)
    "trench_narrow": ("braking_track", {"ditch_length_m": 0.4, "ditch_width_m": 6.0, "ditch_depth_m": 1.0}),
    # a 1 m pit under the right wheels (centre 0.8 m right of the centre line)
    "pit_offcentre": (
        "braking_track",
        {"ditch_length_m": 1.0, "ditch_width_m": 1.0, "ditch_depth_m": 0.8, "lateral_offset_m": 0.8},
    ),
    # no obstacle at all: every veto is a false veto
    "free_track": ("rough_track", {"length_m": 160.0}),
}


def obstacle_free(scenario: str) -> bool:
    """Whether a campaign scenario has no obstacle (its preset is ``rough_track``): there every
    veto is a false one, and ``free_track_steps`` bounds its episodes."""
    return SCENARIOS[scenario][0] == "rough_track"


#: ``paths.csv`` of the braking and policy campaigns: the car's pose and speed at the reset and
#: after every step of each episode (``negobs eval paths`` draws them)
PATH_COLUMNS = (
    "episode",
    "filter",
    "seed",
    "step",
    "x_m",
    "y_m",
    "yaw_rad",
    "speed_mps",
    "vetoed",
    "missed_veto",
)
DRIVERS = ("reckless", "constant_speed")  # scripted; "sb3" joins when a model is given
OBSTACLE_DISTANCE_M = (20.0, 40.0)  # Braking-v0's ditch distance range
TIME_LIMIT_S = 15.0  # Braking-v0's episode length: 104 m at 25 km/h
EPISODE_STEPS = round(TIME_LIMIT_S * 10)  # the most steps of an episode: 150 at the envs' 10 Hz

COLUMNS = (
    "episode",
    "scenario",
    "driver",
    "filter",
    "seed",
    "steps",
    "distance_m",
    "progress_m",
    "entered",
    "collision",
    "rollover",
    "trapped",
    "goal",
    "stopped",
    "start_gap_m",
    "final_gap_m",
    "first_veto_gap_m",
    "vetoes",
    "veto_events",
    "false_vetoes",
    "missed_vetoes",
    "max_veto_error_m",
    "cost",
)


@dataclass(frozen=True, kw_only=True)
class BrakingCampaignConfig:
    """Which configurations the braking campaign runs."""

    seeds: int = 10
    scenarios: tuple[str, ...] = tuple(SCENARIOS)
    drivers: tuple[str, ...] = DRIVERS
    filters: tuple[bool, ...] = (False, True)
    model_path: str | None = None  # a saved SB3 model or a shipped policy's name: adds the driver "sb3"
    algo: str = "PPO"  # its stable-baselines3 class
    rig: str = "roi"  # the envs' default observation rig (ObservationConfig.rig); "native", "reduced"
    tighten_pairs: bool = True  # ObservationConfig.tighten_pairs of the detector the filter reads
    scan_every: int = 1  # ObservationConfig.scan_every: a LiDAR frame every this many steps
    scan_far_from_m: float | None = None  # ObservationConfig.scan_far_from_m: cast beyond it between
    # the most steps (10 Hz) of a free_track episode: the 15 s limit's 150 by default; fewer give a
    # quicker (shorter-distance) false-veto check, the obstacle scenarios keep their 150
    free_track_steps: int = EPISODE_STEPS

    def __post_init__(self) -> None:
        require(self.seeds >= 1, "seeds", f"must be >= 1, got {self.seeds}")
        unknown = sorted(set(self.scenarios) - set(SCENARIOS))
        require(not unknown, "scenarios", f"unknown {unknown}; known: {sorted(SCENARIOS)}")
        known_drivers = (*DRIVERS, "sb3")
        bad = sorted(set(self.drivers) - set(known_drivers))
        require(not bad, "drivers", f"unknown {bad}; known: {list(known_drivers)}")
        require(
            "sb3" not in self.drivers or self.model_path is not None,
            "model_path",
            "driver 'sb3' needs a saved model",
        )
        require(self.rig in RIGS, "rig", f"must be one of {RIGS}, got {self.rig!r}")
        if self.model_path is not None:
            from negobs_gym.drivers.zoo import resolve_model

            resolve_model(self.model_path)  # exists, or names a shipped policy; kept as given
        require(
            isinstance(self.tighten_pairs, bool),
            "tighten_pairs",
            f"must be a bool, got {self.tighten_pairs!r}",
        )
        require(
            type(self.scan_every) is int and self.scan_every >= 1,
            "scan_every",
            f"must be an int >= 1, got {self.scan_every!r}",
        )
        if self.scan_far_from_m is not None:  # the field's own checks, with its name
            ObservationConfig(scan_every=self.scan_every, scan_far_from_m=self.scan_far_from_m)
        require(
            isinstance(self.free_track_steps, int)
            and not isinstance(self.free_track_steps, bool)
            and 1 <= self.free_track_steps <= EPISODE_STEPS,
            "free_track_steps",
            f"must be an int in 1..{EPISODE_STEPS} (the {TIME_LIMIT_S:g} s limit), "
            f"got {self.free_track_steps!r}",
        )
        require(bool(self.scenarios) and bool(self.drivers) and bool(self.filters), "scenarios", "empty")

    def all_drivers(self) -> tuple[str, ...]:
        """The drivers run, ``sb3`` added when a model is given."""
        extra = ("sb3",) if self.model_path is not None and "sb3" not in self.drivers else ()
        return self.drivers + extra


def configuration_name(scenario: str, driver: str, filtered: bool) -> str:
    """``scenario/driver/filter|nofilter``: one line of the summary."""
    return f"{scenario}/{driver}/{'filter' if filtered else 'nofilter'}"


def episodes(config: BrakingCampaignConfig) -> list[Episode]:
    """scenario x driver x filter x seed, keyed in that order. An obstacle-free (``free_track``)
    episode's args hold its ``max_steps`` where ``config.free_track_steps`` is not
    :data:`EPISODE_STEPS`, which the others run, and every episode's its ``scan_every`` where
    that is not 1 and its ``scan_far_from_m`` where set (so a default campaign's parts are those
    written before the fields came)."""
    out = []
    for scenario in config.scenarios:
        for driver in config.all_drivers():
            for filtered in config.filters:
                for seed in range(config.seeds):
                    key = f"{scenario}.{driver}.{int(filtered)}.{seed:05d}"
                    args = {
                        "scenario": scenario,
                        "driver": driver,
                        "filtered": filtered,
                        "seed": seed,
                        "model_path": config.model_path,
                        "algo": config.algo,
                        "rig": config.rig,
                        "tighten_pairs": config.tighten_pairs,
                    }
                    if obstacle_free(scenario) and config.free_track_steps != EPISODE_STEPS:
                        args["max_steps"] = config.free_track_steps
                    if config.scan_every != 1:
                        args["scan_every"] = config.scan_every
                    if config.scan_far_from_m is not None:
                        args["scan_far_from_m"] = config.scan_far_from_m
                    out.append(Episode(key, args))
    return out


def scenario_spec(
    scenario: str,
    rig: str,
    oracle: bool,
    tighten_pairs: bool,
    scan_every: int = 1,
    scan_far_from_m: float | None = None,
) -> Any:
    """The :class:`~negobs_gym.scenarios.ScenarioSpec` of a campaign scenario: Braking-v0's spec
    (25 km/h start, 15 s, no stopping rule: the campaign judges standstill itself) on the
    scenario's terrain, the obstacle's near edge drawn 20-40 m ahead per seed."""
    preset, params = SCENARIOS[scenario]
    data = load_scenario("braking_v0").to_dict()
    data["name"] = f"braking_campaign_{scenario}"
    data["terrain"] = {"preset": preset, "params": dict(params)}
    if preset == "braking_track":
        data["terrain"]["params"]["ditch_distance_m"] = list(OBSTACLE_DISTANCE_M)
    data["episode"]["time_limit_s"] = TIME_LIMIT_S
    spec = ScenarioSpec.from_dict(data)
    # scripted drivers ignore the observation: the oracle grid skips the sensors unless the
    # filter asks for the detector (it always sees obstacles through the detector grid)
    observation = dataclasses.replace(
        spec.observation,
        rig=rig,
        source="oracle" if oracle else "detector",
        tighten_pairs=tighten_pairs,
        scan_every=scan_every,
        scan_far_from_m=scan_far_from_m,
    )
    return dataclasses.replace(spec, observation=observation)


def _scenario_env(
    scenario: str,
    rig: str,
    oracle: bool,
    tighten_pairs: bool,
    render_mode: str | None = None,
    scan_every: int = 1,
    scan_far_from_m: float | None = None,
) -> Any:
    spec = scenario_spec(scenario, rig, oracle, tighten_pairs, scan_every, scan_far_from_m)
    return NegObsEnv(scenario=spec, render_mode=render_mode)


def make_driver(name: str, model_path: str | None = None, algo: str = "PPO") -> Any:
    """A driver by name: ``reckless``, ``constant_speed`` or ``sb3`` (``model_path`` needed)."""
    from negobs_gym.drivers import ConstantSpeedDriver, RecklessDriver

    if name == "reckless":
        return RecklessDriver()
    if name == "constant_speed":
        return ConstantSpeedDriver()
    if name == "sb3":
        if model_path is None:
            raise ConfigError("model_path", "driver 'sb3' needs a saved model")
        return ModelDriver(model_path, algo)
    raise ConfigError("driver", f"unknown driver {name!r}")


def run_driven_episode(
    env: Any,
    driver: Any,
    seed: int,
    filtered: bool | SafetyFilterConfig,
    max_steps: int,
    video_to: str | Path | None = None,
) -> dict[str, Any]:
    """One episode of ``driver`` on ``env`` (wrapped in the filter when ``filtered``: True for the
    default settings or a :class:`~negobs_gym.safety.SafetyFilterConfig`); its metrics.
    ``video_to``: also write the episode's frames there (:class:`~negobs_gym.envs.video.
    EpisodeVideo`; ``env`` renders ``rgb_array``); the metrics are the same with or without.

    Ends on termination, truncation, ``max_steps`` or a standstill of ``STANDSTILL_S``. Gaps are
    ground truth from the front bumper to the nearest negative obstacle ahead (inf: none ahead);
    ``off_track_steps`` counts the steps that ended off the track (``info["off_track"]``: farther
    from the centre line than half the track width); ``left_track`` is whether that ended the
    episode (the env's ``off_track`` termination rule, OffroadNav-v2). ``path`` holds one
    ``(x, y, yaw, speed, vetoed, missed_veto)`` per step (world metres, radians, m/s, bools), the
    reset's first; ``judgements`` each veto and missed veto
    (:class:`~negobs_gym.eval.vetoes.VetoJudgement`).
    ``false_vetoes``: the vetoes with no true obstacle where the filter saw its hazard (along the
    corridor it searched: :func:`~negobs_gym.eval.vetoes.is_false_veto`); ``missed_vetoes``: the
    steps it let through with a true hazard well inside R(v)
    (:func:`~negobs_gym.eval.vetoes.is_missed_veto`); ``max_veto_error_m``: the largest distance a
    veto acted on minus its ground truth (:func:`~negobs_gym.eval.vetoes.veto_error_m`; > 0: the
    filter saw the hazard farther than it was), NaN when no veto had a true obstacle to judge by.
    """
    from negobs_gym.safety import BrakingSafetyFilter

    guard = filter_config(filtered)
    if guard is not None:
        env = BrakingSafetyFilter(env, config=guard)
    with contextlib.closing(env), optional_video(video_to, fps=env.unwrapped.scenario.episode.control_hz) as video:
        return _driven_episode(recording(env, video), driver, seed, guard, max_steps)


def _driven_episode(
    env: Any,
    driver: Any,
    seed: int,
    guard: SafetyFilterConfig | None,
    max_steps: int,
) -> dict[str, Any]:
    """The episode of :func:`run_driven_episode` in ``env`` (filter applied)."""
    driver.reset(seed)
    obs, info = env.reset(seed=seed)
    dt = 1.0 / env.unwrapped.scenario.episode.control_hz
    start_gap, start_station = float(info["distance_to_negative_ahead_m"]), float(info["station_m"])
    first_veto, cost, still_s, steps, distance = math.nan, 0.0, 0.0, 0, 0.0
    tally = VetoTally(positive=guard is not None and guard.stop_for_positive)
    events = {"entered_negative_obstacle": False, "collision": False, "rollover": False, "trapped": False}
    goal, done, off_track_steps = False, False, 0
    last_xy = np.asarray(info["pose"][:2], dtype=np.float64)
    path = [_path_point(info, False, False)]
    while not done and steps < max_steps:
        before, gap = info, float(info["distance_to_negative_ahead_m"])
        obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
        steps += 1
        xy = np.asarray(info["pose"][:2], dtype=np.float64)
        distance += float(np.hypot(*(xy - last_xy)))
        last_xy = xy
        for k in events:
            events[k] |= bool(info["events"][k])
        goal |= bool(info.get("goal_reached", False))
        off_track_steps += bool(info.get("off_track", False))
        vetoed, missed = tally.add(env.unwrapped, info.get("safety"), before, steps)
        if vetoed and math.isnan(first_veto):
            first_veto = gap
        path.append(_path_point(info, vetoed, missed))
        cost += float(info.get("cost", 0.0))
        still_s = still_s + dt if info["speed_mps"] < STANDSTILL_MPS else 0.0
        done = terminated or truncated or still_s >= STANDSTILL_S
    return {
        "steps": steps,
        "distance_m": distance,
        "progress_m": float(info["station_m"]) - start_station,
        "entered": events["entered_negative_obstacle"],
        "collision": events["collision"],
        "rollover": events["rollover"],
        "trapped": events["trapped"],
        "goal": goal,
        "off_track_steps": off_track_steps,
        "left_track": "off_track" in info.get("termination", ()),
        "stopped": still_s >= STANDSTILL_S,
        "start_gap_m": start_gap,
        "final_gap_m": float(info["distance_to_negative_ahead_m"]),
        "first_veto_gap_m": first_veto,
        "vetoes": len(tally.vetoed_steps),
        "veto_events": tally.veto_events,
        "false_vetoes": tally.false_vetoes,
        "missed_vetoes": len(tally.missed_steps),
        "max_veto_error_m": largest_veto_error_m(tally.errors_m, math.nan),
        "cost": cost,
        "path": path,
        "judgements": tally.judgements,
    }


def _path_point(
    info: dict[str, Any], vetoed: bool, missed: bool
) -> tuple[float, float, float, float, bool, bool]:
    x, y, _, _, _, yaw = (float(v) for v in info["pose"])
    return x, y, yaw, float(info["speed_mps"]), vetoed, missed


def path_rows(key: str, filter_label: str, seed: int, path: Sequence[tuple]) -> list[str]:
    """An episode's ``path`` (:func:`run_driven_episode`) as rows of :data:`PATH_COLUMNS`."""
    return [format_row([key, filter_label, seed, step, *point]) for step, point in enumerate(path)]


def run_episode(episode: Episode) -> Rows:
    """One braking episode of :func:`episodes`; one row of :data:`COLUMNS`. An arg ``video_to`` (not
    set by :func:`episodes`; :func:`negobs_gym.eval.replay.replay_videos`) also writes its frames."""
    a = episode.args
    video_to = a.get("video_to")
    driver = make_driver(a["driver"], a["model_path"], a["algo"])
    render_mode = "rgb_array" if video_to is not None else None
    env = _scenario_env(
        a["scenario"],
        a["rig"],
        a["driver"] != "sb3",
        a["tighten_pairs"],
        render_mode,
        a.get("scan_every", 1),
        a.get("scan_far_from_m"),
    )
    max_steps = a.get("max_steps", EPISODE_STEPS)
    metrics = run_driven_episode(env, driver, a["seed"], a["filtered"], max_steps, video_to=video_to)
    label = "filter" if a["filtered"] else "nofilter"
    row = [episode.key, a["scenario"], a["driver"], label, a["seed"]]
    return {
        "braking": [format_row(row + [metrics[c] for c in COLUMNS[5:]])],
        "paths": path_rows(episode.key, label, a["seed"], metrics["path"]),
        "vetoes": veto_rows(episode.key, label, a["seed"], metrics["judgements"]),
    }


# -- summary -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class ConfigurationSummary:
    """Totals of one scenario x driver x filter configuration."""

    name: str
    obstacle: bool
    episodes: int
    entries: int
    stopped_before: int  # stopped short of the obstacle without entering it
    km: float
    veto_events: int
    false_vetoes_per_km: float | None  # obstacle-free scenarios only
    stop_margins_m: list[float]  # final gap of the stops before the obstacle
    first_veto_gaps_m: list[float]
    missed_vetoes: int = 0  # steps let through with a true hazard 2 m inside R(v) (eval.vetoes)
    max_veto_error_m: float | None = None  # largest veto distance minus its truth (eval.vetoes)
    veto_errors_m: list[float] = field(default_factory=list)  # every judged veto's (vetoes.csv)
    onset_veto_errors_m: list[float] = field(default_factory=list)  # the onset vetoes' alone

    @property
    def stopped_before_interval(self) -> tuple[float, float] | None:
        """The 95 % Wilson interval of the stopped-before rate (None: an obstacle-free scenario)."""
        return rate_interval(self.stopped_before, self.episodes) if self.obstacle else None

    @property
    def median_veto_error_m(self) -> float | None:
        """The median of :attr:`veto_errors_m` (None: none judged, or no ``vetoes.csv`` read)."""
        return median_or_none(self.veto_errors_m)

    @property
    def median_onset_veto_error_m(self) -> float | None:
        """The median of :attr:`onset_veto_errors_m`: where the braking events began, against the
        truth (None: none judged, or no ``vetoes.csv`` read)."""
        return median_or_none(self.onset_veto_errors_m)


def median_or_none(values: Sequence[float]) -> float | None:
    """The median of ``values``; None when there are none."""
    return float(np.median(values)) if values else None


def _flag(row: Mapping[str, str], key: str) -> bool:
    return row[key] == "1"


def veto_errors_by(
    vetoes_csv: str | Path, group: Callable[[dict[str, str]], str]
) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
    """Every judged veto error of a ``vetoes.csv`` (:data:`VETO_COLUMNS`; vetoes whose ``error_m``
    is not NaN), in row order, grouped by ``group(row)``; and the same of the onset vetoes alone
    (``onset`` = 1: those that began a braking event). One pass over the file."""
    errors: dict[str, list[float]] = {}
    onsets: dict[str, list[float]] = {}
    for row in read_csv(vetoes_csv):
        if row["kind"] != "veto" or math.isnan(float(row["error_m"])):
            continue
        key, error = group(row), float(row["error_m"])
        errors.setdefault(key, []).append(error)
        if row["onset"] == "1":
            onsets.setdefault(key, []).append(error)
    return errors, onsets


def summarize(csv_path: str | Path, vetoes_csv: str | Path | None = None) -> list[ConfigurationSummary]:
    """Per-configuration totals from the campaign CSV, in the CSV's configuration order; with its
    ``vetoes.csv`` each configuration's veto errors too (:attr:`ConfigurationSummary.veto_errors_m`)."""
    groups: dict[str, list[dict[str, str]]] = {}
    names: dict[str, str] = {}  # episode -> configuration
    for row in read_csv(csv_path):
        name = configuration_name(row["scenario"], row["driver"], row["filter"] == "filter")
        groups.setdefault(name, []).append(row)
        names[row["episode"]] = name

    def configuration(veto: dict[str, str]) -> str:
        require(
            veto["episode"] in names,
            "vetoes_csv",
            f"{vetoes_csv} has episode {veto['episode']!r}, which {csv_path} lacks: not the same campaign's",
        )
        return names[veto["episode"]]

    errors, onsets = ({}, {}) if vetoes_csv is None else veto_errors_by(vetoes_csv, configuration)
    out = []
    for name, rows in groups.items():
        obstacle = not obstacle_free(rows[0]["scenario"])
        km = sum(float(r["distance_m"]) for r in rows) / 1000.0
        events = sum(int(r["veto_events"]) for r in rows)
        stops = [r for r in rows if obstacle and _flag(r, "stopped") and not _flag(r, "entered")]
        out.append(
            ConfigurationSummary(
                name=name,
                obstacle=obstacle,
                episodes=len(rows),
                entries=sum(_flag(r, "entered") for r in rows),
                stopped_before=len(stops),
                km=km,
                veto_events=events,
                false_vetoes_per_km=None if obstacle else (events / km if km > 0 else None),
                stop_margins_m=[float(r["final_gap_m"]) for r in stops],
                first_veto_gaps_m=[
                    float(r["first_veto_gap_m"]) for r in rows if math.isfinite(float(r["first_veto_gap_m"]))
                ],
                missed_vetoes=sum(int(r["missed_vetoes"]) for r in rows),
                max_veto_error_m=largest_veto_error_m(float(r["max_veto_error_m"]) for r in rows),
                veto_errors_m=errors.get(name, []),
                onset_veto_errors_m=onsets.get(name, []),
            )
        )
    return out


def summary_json(summaries: Sequence[ConfigurationSummary]) -> str:
    """The summaries as JSON (``[ConfigurationSummary(**d) for d in json.loads(text)]`` restores them)."""
    return json.dumps([dataclasses.asdict(s) for s in summaries], indent=1, sort_keys=True)


def summary_line(s: ConfigurationSummary) -> str:
    """The one-line result of a configuration, e.g. ``ditch/reckless/filter stopped_before=9/10 ...``."""
    text = f"{s.name} stopped_before={s.stopped_before}/{s.episodes} entries={s.entries}/{s.episodes}"
    if s.obstacle:
        text += f" stopped_before_interval={format_interval(s.stopped_before_interval)}"
    if s.false_vetoes_per_km is not None:
        text += f" false_vetoes_per_km={s.false_vetoes_per_km:.2f} ({s.veto_events} in {s.km:.3f} km)"
    if s.stop_margins_m:
        text += f" median_stop_margin_m={float(np.median(s.stop_margins_m)):.2f}"
    if s.name.endswith("/filter"):
        text += f" missed_vetoes={s.missed_vetoes} veto_error_m={format_veto_error(s.max_veto_error_m)}"
        if s.veto_errors_m:
            text += f" median_veto_error_m={format_veto_error(s.median_veto_error_m)}"
            text += f" median_onset_veto_error_m={format_veto_error(s.median_onset_veto_error_m)}"
    return text


def report_markdown(summaries: Sequence[ConfigurationSummary]) -> str:
    """The per-configuration table as markdown."""
    from negobs_gym.eval.tables import key_value_table

    rows = [
        [
            s.name,
            s.episodes,
            s.entries,
            s.stopped_before,
            format_interval(s.stopped_before_interval),
            "-" if not s.stop_margins_m else float(np.median(s.stop_margins_m)),
            "-" if not s.first_veto_gaps_m else float(np.median(s.first_veto_gaps_m)),
            "-" if s.false_vetoes_per_km is None else s.false_vetoes_per_km,
            s.missed_vetoes if s.name.endswith("/filter") else "-",
            "-" if s.median_veto_error_m is None else s.median_veto_error_m,
            "-" if s.median_onset_veto_error_m is None else s.median_onset_veto_error_m,
            "-" if s.max_veto_error_m is None else s.max_veto_error_m,
            s.km,
        ]
        for s in summaries
    ]
    header = [
        "configuration",
        "episodes",
        "entries",
        "stopped before",
        "stopped before (95 % interval)",
        "median stop margin [m]",
        "median first-veto gap [m]",
        "false vetoes per km",
        "missed vetoes",
        "median veto error [m]",
        "median onset veto error [m]",
        "largest veto error [m]",
        "km",
    ]
    return "# Braking campaign at 25 km/h\n\n" + key_value_table(header, rows) + "\n"


@dataclass(frozen=True)
class BrakingOutputs:
    """Files of a finished braking campaign."""

    csv: Path
    summary_json: Path
    table_md: Path
    margins_png: Path
    first_veto_png: Path
    veto_errors_png: Path
    summaries: list[ConfigurationSummary]
    vetoes_csv: Path


def run_braking_campaign(
    config: BrakingCampaignConfig,
    out_dir: str | Path,
    options: RunOptions | None = None,
) -> BrakingOutputs:
    """Run (or resume) the braking campaign; CSV, summary JSON, table and plots in ``out_dir``."""
    from negobs_gym.core.files import write_text_atomic
    from negobs_gym.eval.campaign import run_campaign
    from negobs_gym.eval.plots import distribution_plot

    out = Path(out_dir)
    tables = {"braking": COLUMNS, "paths": PATH_COLUMNS, "vetoes": VETO_COLUMNS}
    csvs = run_campaign(run_episode, episodes(config), out, tables, options, "braking episodes")
    csv = csvs["braking"]
    summaries = summarize(csv, csvs["vetoes"])
    obstacle = [s for s in summaries if s.obstacle]
    return BrakingOutputs(
        csv=csv,
        summary_json=write_text_atomic(out / "summary.json", summary_json(summaries)),
        table_md=write_text_atomic(out / "table.md", report_markdown(summaries)),
        margins_png=distribution_plot(
            {s.name: s.stop_margins_m for s in obstacle},
            "gap left between the front bumper and the obstacle at standstill [m]",
            "Stop margins of the runs that stopped before the obstacle",
            out / "stop_margins.png",
        ),
        first_veto_png=distribution_plot(
            {s.name: s.first_veto_gaps_m for s in summaries if s.name.endswith("/filter")},
            "gap to the obstacle when the filter first braked [m]",
            "First-veto distance of the filtered runs",
            out / "first_veto.png",
        ),
        veto_errors_png=distribution_plot(
            {s.name: s.veto_errors_m for s in summaries if s.name.endswith("/filter")},
            "distance the filter acted on minus the true one along its corridor [m]",
            "Veto errors of the filtered runs (> 0: the hazard seen farther than it was)",
            out / "veto_errors.png",
        ),
        summaries=summaries,
        vetoes_csv=csvs["vetoes"],
    )
