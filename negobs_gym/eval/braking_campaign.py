"""Braking campaign at 25 km/h: drivers with and without the Eq. 18 safety filter, per scenario.

Configurations are data: every scenario of :data:`SCENARIOS` (paper N's pit sizes, the Braking
ditch, a narrow trench, an off-centre pit, an obstacle-free track for false vetoes; each the
shipped scene ``braking_campaign_<scenario>`` of ``negobs_gym/spec/scenes``, changed for the
whole campaign by ``overrides``, the ``--set KEY.PATH=VALUE`` paths) x every driver (scripted
drivers of :mod:`negobs_gym.drivers`, optionally a saved SB3 model) x filter off / on
(:class:`~negobs_gym.safety.BrakingSafetyFilter`), each run on seeds 0..n-1 by the one episode
loop (:func:`~negobs_gym.eval.episode.drive_episode`). One CSV row per episode (:data:`COLUMNS`),
each episode's path in ``paths.csv`` (:data:`PATH_COLUMNS`, drawn by ``negobs eval paths``), and
each veto and missed veto judged on the ground truth in ``vetoes.csv`` (:data:`VETO_COLUMNS`);
:func:`summarize` turns the CSVs into per-configuration counts.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.core.files import write_text_atomic
from negobs_gym.drivers import ConstantSpeedDriver, Driver, ModelDriver, RecklessDriver
from negobs_gym.drivers.zoo import resolve_model
from negobs_gym.envs import make_env
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.campaign import (
    Episode,
    Rows,
    RunOptions,
    format_row,
    read_csv,
    run_campaign,
    scene_assignments,
)
from negobs_gym.eval.episode import STANDSTILL_S, EpisodeResult, EpisodeStop, drive_episode
from negobs_gym.eval.plots import distribution_plot
from negobs_gym.eval.stats import format_interval, rate_interval
from negobs_gym.eval.tables import key_value_table
from negobs_gym.eval.vetoes import (
    VETO_COLUMNS,
    format_veto_error,
    largest_veto_error_m,
    veto_rows,
)
from negobs_gym.safety.config import SafetyFilterConfig, filter_config
from negobs_gym.spec import ScenarioSpec, apply_overrides, load_scenario

#: The campaign's scenarios, each the shipped scene ``braking_campaign_<name>``: Braking-v0's
#: episode (25 km/h start, 15 s) on Braking-v0's ditch, paper N §4.1's pit sizes (100 x 50,
#: 100 x 80, 150 x 60 and 100 x 100 cm, the long side across the track), a narrow trench across
#: the track, a pit under the right wheels (each near edge drawn 20-40 m ahead per seed), and a
#: track with no obstacle at all, where every veto is a false one.
SCENARIOS: tuple[str, ...] = (
    "ditch",
    "pit_100x50",
    "pit_100x80",
    "pit_150x60",
    "pit_100x100",
    "trench_narrow",
    "pit_offcentre",
    "free_track",
)
SCENE_PREFIX = "braking_campaign_"
DRIVERS = ("reckless", "constant_speed")  # scripted; "sb3" joins when a model is given
EPISODE_STEPS = 150  # the most steps of a campaign scene's episode: its 15 s limit at the envs' 10 Hz
#: The loop's own end: 1 s standing still is a stop (the scenes have no stopping rule)
STOP = EpisodeStop(standstill_s=STANDSTILL_S)
#: ``negobs eval braking``'s options that set a field of the scenes, each as the ``--set`` path
#: it stands for; the config once copied them as fields of its own, which still work for one
#: release, with a warning, as these assignments before ``overrides``
SCENE_FIELDS: dict[str, str] = {
    "rig": "observation.rig",
    "tighten_pairs": "observation.tighten_pairs",
    "scan_every": "observation.scan_every",
    "scan_far_from_m": "observation.scan_far_from_m",
}


def scene_name(scenario: str) -> str:
    """The shipped scene of a campaign scenario: ``braking_campaign_<scenario>``."""
    return SCENE_PREFIX + scenario


@functools.cache
def scene(scenario: str) -> ScenarioSpec:
    """The shipped scene of a campaign scenario (:func:`scene_name`)."""
    require(scenario in SCENARIOS, "scenarios", f"unknown {scenario!r}; known: {sorted(SCENARIOS)}")
    return load_scenario(scene_name(scenario))


def obstacle_free(scenario: str) -> bool:
    """Whether a campaign scenario has no obstacle (its scene's terrain is the ``rough_track``
    preset, which has none): there every veto is a false one, and ``free_track_steps`` bounds its
    episodes."""
    return scene(scenario).terrain.preset == "rough_track"


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
    """Which configurations the braking campaign runs, and the changes to its scenes.

    ``overrides``: ``KEY.PATH=VALUE`` assignments applied to every scene (the ``--set`` paths of
    ``negobs eval braking``; ``("observation.rig=native", "observation.scan_every=3")``), after
    the campaign's own ``observation.source=oracle`` for the scripted drivers, who ignore the
    observation (the filter reads the detector grid whatever the source).
    """

    seeds: int = 10
    scenarios: tuple[str, ...] = SCENARIOS
    drivers: tuple[str, ...] = DRIVERS
    filters: tuple[bool, ...] = (False, True)
    model_path: str | None = None  # a saved SB3 model or a shipped policy's name: adds the driver "sb3"
    algo: str = "PPO"  # its stable-baselines3 class
    overrides: tuple[str, ...] = ()
    # the most steps (10 Hz) of a free_track episode: the 15 s limit's 150 by default; fewer give a
    # quicker (shorter-distance) false-veto check, the obstacle scenarios keep their scene's limit
    free_track_steps: int = EPISODE_STEPS
    # deprecated, one release: the SCENE_FIELDS paths in overrides
    rig: dataclasses.InitVar[str | None] = None
    tighten_pairs: dataclasses.InitVar[bool | None] = None
    scan_every: dataclasses.InitVar[int | None] = None
    scan_far_from_m: dataclasses.InitVar[float | None] = None

    def __post_init__(
        self,
        rig: str | None,
        tighten_pairs: bool | None,
        scan_every: int | None,
        scan_far_from_m: float | None,
    ) -> None:
        old = {"rig": rig, "tighten_pairs": tighten_pairs, "scan_every": scan_every}
        moved = scene_assignments({**old, "scan_far_from_m": scan_far_from_m}, SCENE_FIELDS)
        if moved:
            warnings.warn(
                f"BrakingCampaignConfig's scene fields are deprecated: give overrides={tuple(moved)!r}",
                DeprecationWarning,
                stacklevel=3,
            )
            object.__setattr__(self, "overrides", (*moved, *self.overrides))
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
        if self.model_path is not None:
            resolve_model(self.model_path)  # exists, or names a shipped policy; kept as given
        require(
            isinstance(self.overrides, tuple) and all(isinstance(o, str) for o in self.overrides),
            "overrides",
            f"must be a tuple of KEY.PATH=VALUE texts, got {self.overrides!r}",
        )
        for scenario in self.scenarios:  # a bad path or value: an error naming it, before any episode
            apply_overrides(scene(scenario), self.overrides)
        require(
            isinstance(self.free_track_steps, int)
            and not isinstance(self.free_track_steps, bool)
            and 1 <= self.free_track_steps <= EPISODE_STEPS,
            "free_track_steps",
            f"must be an int in 1..{EPISODE_STEPS} (the 15 s limit), got {self.free_track_steps!r}",
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
    """scenario x driver x filter x seed, keyed in that order. An episode's args hold the
    campaign's ``overrides`` where there are any, and an obstacle-free (``free_track``) episode's
    its ``max_steps`` where ``config.free_track_steps`` is not :data:`EPISODE_STEPS`."""
    out = []
    for scenario in config.scenarios:
        for driver in config.all_drivers():
            for filtered in config.filters:
                for seed in range(config.seeds):
                    key = f"{scenario}.{driver}.{int(filtered)}.{seed:05d}"
                    args: dict[str, Any] = {
                        "scenario": scenario,
                        "driver": driver,
                        "filtered": filtered,
                        "seed": seed,
                        "model_path": config.model_path,
                        "algo": config.algo,
                    }
                    if config.overrides:
                        args["overrides"] = list(config.overrides)
                    if obstacle_free(scenario) and config.free_track_steps != EPISODE_STEPS:
                        args["max_steps"] = config.free_track_steps
                    out.append(Episode(key, args))
    return out


def episode_overrides(args: Mapping[str, Any]) -> list[str]:
    """The assignments an episode's scene runs with: the oracle grid for a scripted driver (it
    ignores the observation; the filter reads the detector grid whatever the source), then the
    campaign's ``overrides``."""
    source = ["observation.source=oracle"] if args["driver"] != "sb3" else []
    return [*source, *args.get("overrides", ())]


def make_driver(name: str, model_path: str | None = None, algo: str = "PPO") -> Driver:
    """A driver by name: ``reckless``, ``constant_speed`` or ``sb3`` (``model_path`` needed)."""
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
    """Deprecated, kept for one release: :func:`~negobs_gym.eval.episode.drive_episode` with
    ``EpisodeStop(max_steps=max_steps, standstill_s=STANDSTILL_S)``, whose result's
    :meth:`~negobs_gym.eval.episode.EpisodeResult.metrics` this returns with ``path`` (one
    ``(x, y, yaw, speed, vetoed, missed_veto)`` per step) and ``judgements``; closes ``env``."""
    warnings.warn(
        "negobs_gym.eval.braking_campaign.run_driven_episode is deprecated: use "
        "negobs_gym.eval.episode.drive_episode, which returns an EpisodeResult",
        DeprecationWarning,
        stacklevel=2,
    )
    stop = EpisodeStop(max_steps=max_steps, standstill_s=STANDSTILL_S)
    with contextlib.closing(env):
        result = drive_episode(
            env, driver, seed=seed, filter=filter_config(filtered) or False, stop=stop, video_to=video_to
        )
    vetoed, missed = set(result.vetoed_steps), set(result.missed_steps)
    path = [(*point, step in vetoed, step in missed) for step, point in enumerate(result.path)]
    return {**result.metrics(), "path": path, "judgements": list(result.veto_judgements)}


def path_rows(key: str, filter_label: str, seed: int, result: EpisodeResult) -> list[str]:
    """An episode's path (:attr:`EpisodeResult.path`, its vetoed and missed steps marked) as
    rows of :data:`PATH_COLUMNS`."""
    vetoed, missed = set(result.vetoed_steps), set(result.missed_steps)
    return [
        format_row([key, filter_label, seed, step, *point, step in vetoed, step in missed])
        for step, point in enumerate(result.path)
    ]


def run_episode(episode: Episode) -> Rows:
    """One braking episode of :func:`episodes`; one row of :data:`COLUMNS`. An arg ``video_to`` (not
    set by :func:`episodes`; :func:`negobs_gym.eval.replay.replay_videos`) also writes its frames."""
    a = episode.args
    video_to = a.get("video_to")
    driver = make_driver(a["driver"], a["model_path"], a["algo"])
    render_mode = "rgb_array" if video_to is not None else None
    env = make_env(scene_name(a["scenario"]), episode_overrides(a), render_mode=render_mode)
    stop = dataclasses.replace(STOP, max_steps=a.get("max_steps"))
    with contextlib.closing(env):
        result = drive_episode(
            env, driver, seed=a["seed"], filter=bool(a["filtered"]), stop=stop, video_to=video_to
        )
    metrics = result.metrics()
    label = "filter" if a["filtered"] else "nofilter"
    row = [episode.key, a["scenario"], a["driver"], label, a["seed"]]
    return {
        "braking": [format_row(row + [metrics[c] for c in COLUMNS[5:]])],
        "paths": path_rows(episode.key, label, a["seed"], result),
        "vetoes": veto_rows(episode.key, label, a["seed"], result.veto_judgements),
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
