"""Evaluate a saved stable-baselines3 model on a registered env over seeds, with and without the filter.

One CSV row per episode (:data:`COLUMNS`): success (no negative-obstacle entry, collision,
rollover or trap during the episode, and it did not end by leaving the track), the failure events,
whether leaving the track ended it (OffroadTrack-v0's ``off_track`` rule), goal reached, progress
along the track, distance driven, the filter's vetoes (steps) and the false ones among them (no
true obstacle where the filter saw its hazard, :func:`~negobs_gym.eval.vetoes.is_false_veto`),
the braking events they make up (runs of vetoed steps, each begun by an onset veto), the
steps it let through with a true hazard well inside R(v) (missed vetoes,
:func:`~negobs_gym.eval.vetoes.is_missed_veto`), the summed constraint ``cost``
(``info["cost"]``), the largest error of a veto's hazard distance (the distance it acted on
minus the true one, :func:`~negobs_gym.eval.vetoes.veto_error_m`; NaN: no veto to judge) and the
steps that ended off the track (farther from the centre line than half the track width: the
obstacles of OffroadNav lie on the track, so a policy that drives beside it meets none), whether
a standstill ended it (``stopped``: 1 s at rest, e.g. held by the filter) and the steps whose
steering the filter changed ahead of a veto (``steered_steps``, its ``steer_search``). Each
veto and missed veto, judged on the ground truth, is a row of ``vetoes.csv``
(:data:`~negobs_gym.eval.vetoes.VETO_COLUMNS`), each step of each episode one of
``paths.csv``.

Seeds start at ``first_seed`` (default 1,000,000, the seeds ``negobs train`` evaluates on): a
training run's envs reset from seeds ``seed + i`` and then draw their terrains from their own
generators, so these seeds are terrains the policy has not trained on.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from negobs_gym.core.files import write_text_atomic
from negobs_gym.drivers import DRIVER_NAMES, ModelDriver
from negobs_gym.drivers.zoo import resolve_model
from negobs_gym.envs import make_env, source_overrides
from negobs_gym.errors import require
from negobs_gym.eval.braking_campaign import PATH_COLUMNS, median_or_none, path_rows, veto_errors_by
from negobs_gym.eval.campaign import (
    Episode,
    Rows,
    RunOptions,
    format_row,
    read_csv,
    run_campaign,
    scene_assignments,
)
from negobs_gym.eval.episode import STANDSTILL_S, DriverSource, EpisodeStop, drive_episode
from negobs_gym.eval.scenario_runner import make_driver
from negobs_gym.eval.stats import rate_interval
from negobs_gym.eval.vetoes import VETO_COLUMNS, largest_veto_error_m, veto_rows
from negobs_gym.spec import apply_overrides, spec_for_env

#: ``negobs eval policy``'s option that sets a field of the env's scenario, as the ``--set`` path
#: it stands for; the config once copied it as a field of its own, which still works for one
#: release, with a warning, as this assignment before ``overrides``
SCENE_FIELDS: dict[str, str] = {"source": "observation.source"}
DEFAULT_MAX_STEPS = 1000  # for env ids registered without max_episode_steps (100 s at 10 Hz)

COLUMNS = (
    "episode",
    "env",
    "filter",
    "seed",
    "success",
    "entered",
    "collision",
    "rollover",
    "trapped",
    "left_track",
    "goal",
    "progress_m",
    "distance_m",
    "steps",
    "vetoes",
    "veto_events",
    "false_vetoes",
    "missed_vetoes",
    "max_veto_error_m",
    "cost",
    "off_track_steps",
    "stopped",
    "steered_steps",
)


#: Per filter setting, summed over the episodes in :func:`summarize`.
SUMMED = (
    "episodes",
    "successes",
    "goals",
    "entries",
    "collisions",
    "left_track",
    "progress_m",
    "distance_m",
    "vetoes",
    "veto_events",
    "false_vetoes",
    "missed_vetoes",
    "cost",
    "steps",
    "off_track_steps",
    "stopped",
    "steered_steps",
)


@dataclass(frozen=True, kw_only=True)
class PolicyCampaignConfig:
    """A saved model, the env id it runs on, the seeds and the filter settings.

    ``overrides``: ``KEY.PATH=VALUE`` assignments to the env's scenario (the ``--set`` paths;
    ``("observation.source=oracle",)`` gives the oracle grid instead of the detector grid every
    registered id observes, e.g. to evaluate a policy on what it was trained on).
    ``stop_for_positive``: True, the filtered episodes' filter also stops for the grid's
    positive-obstacle cells (:class:`~negobs_gym.safety.SafetyFilterConfig`); False, it does
    not; None, as the scene's ``filter.stop_for_positive`` says (after the overrides). The rows of
    a filter that stops for them say ``filter_positive`` instead of ``filter``.
    ``model_path``: a saved model, or the name of a shipped policy, which the episodes' records
    keep as a name (resolved where each runs), so a campaign folder replays on another install
    (``negobs eval video``); or a scripted driver's name
    (:data:`~negobs_gym.drivers.DRIVER_NAMES`), built on each course at its scene's
    ``run.target_speed_mps`` and ``run.lane_offset_m`` (``algo`` unused): the same campaign,
    filter and judges for a scripted driver, e.g. the privileged track planner on both grids
    (``negobs pem check --policy track_planner``).
    """

    model_path: str
    env_id: str = "negobs_gym/Braking-v0"
    algo: str = "PPO"
    seeds: int = 10
    first_seed: int = 1_000_000
    filters: tuple[bool, ...] = (False, True)
    overrides: tuple[str, ...] = ()
    stop_for_positive: bool | None = None
    source: dataclasses.InitVar[str | None] = None  # deprecated, one release: observation.source

    def __post_init__(self, source: str | None) -> None:
        moved = scene_assignments({"source": source}, SCENE_FIELDS)
        if moved:
            warnings.warn(
                f"PolicyCampaignConfig.source is deprecated: give overrides={tuple(moved)!r}",
                DeprecationWarning,
                stacklevel=3,
            )
            object.__setattr__(self, "overrides", (*moved, *self.overrides))
        require(self.seeds >= 1, "seeds", f"must be >= 1, got {self.seeds}")
        require(self.first_seed >= 0, "first_seed", f"must be >= 0, got {self.first_seed}")
        require(
            isinstance(self.overrides, tuple) and all(isinstance(o, str) for o in self.overrides),
            "overrides",
            f"must be a tuple of KEY.PATH=VALUE texts, got {self.overrides!r}",
        )
        if self.overrides:  # a bad path or value: named now, not in the first episode
            apply_overrides(spec_for_env(self.env_id), self.overrides)
        require(bool(self.filters), "filters", "needs at least one of off / on")
        require(
            self.stop_for_positive is None or isinstance(self.stop_for_positive, bool),
            "stop_for_positive",
            f"must be a bool or None (the scene's), got {self.stop_for_positive!r}",
        )
        if self.model_path not in DRIVER_NAMES:
            resolve_model(self.model_path)  # a saved model or a shipped one's name, kept as given


def filter_label(filtered: bool, stop_for_positive: bool) -> str:
    """The ``filter`` column: ``nofilter``, ``filter`` or ``filter_positive``."""
    if not filtered:
        return "nofilter"
    return "filter_positive" if stop_for_positive else "filter"


def episodes(config: PolicyCampaignConfig) -> list[Episode]:
    """filter x seed; the args hold the campaign's ``overrides`` where there are any."""
    args: dict[str, Any] = {
        "model_path": config.model_path,
        "env_id": config.env_id,
        "algo": config.algo,
        "stop_for_positive": config.stop_for_positive,
    }
    if config.overrides:
        args["overrides"] = list(config.overrides)
    seeds = range(config.first_seed, config.first_seed + config.seeds)
    code = {False: 0, True: 2 if config.stop_for_positive else 1}  # keys of filter_label's rows
    return [
        Episode(f"{code[bool(f)]}.{seed:07d}", {**args, "filtered": f, "seed": seed})
        for f in config.filters
        for seed in seeds
    ]


def _driver(model_path: str, algo: str) -> DriverSource:
    """The episode's driver: the scripted driver of that name, built on the reset env's course at its
    scene's speed and lane offset, else the saved model."""
    if model_path in DRIVER_NAMES:
        return lambda env: make_driver(model_path, env.scenario, env.terrain)
    return ModelDriver(model_path, algo)


def run_episode(episode: Episode) -> Rows:
    """One episode of the model on ``env_id`` (a registered id, a shipped scenario or a TOML
    file) with the campaign's overrides. An arg ``video_to`` (not set by :func:`episodes`; see
    :func:`negobs_gym.eval.replay.replay_videos`) also writes its frames there."""
    a = episode.args
    video_to = a.get("video_to")
    render_mode = "rgb_array" if video_to is not None else None
    # a campaign of an earlier version recorded its grid source as the arg "source"
    overrides = [*source_overrides(a.get("source")), *a.get("overrides", ())]
    env = make_env(a["env_id"], overrides, render_mode=render_mode)
    max_steps = env.spec.max_episode_steps if env.spec and env.spec.max_episode_steps else DEFAULT_MAX_STEPS
    own = env.unwrapped.scenario.filter  # the scene's [filter] settings, the campaign's switch on top
    positive = own.stop_for_positive if a["stop_for_positive"] is None else a["stop_for_positive"]
    guard = dataclasses.replace(own, stop_for_positive=positive) if a["filtered"] else False
    driver = _driver(a["model_path"], a["algo"])
    stop = EpisodeStop(max_steps=max_steps, standstill_s=STANDSTILL_S)
    with contextlib.closing(env):
        result = drive_episode(env, driver, seed=a["seed"], filter=guard, stop=stop, video_to=video_to)
    m = result.metrics()
    success = not (m["entered"] or m["collision"] or m["rollover"] or m["trapped"] or m["left_track"])
    label = filter_label(a["filtered"], positive)
    row: list[Any] = [episode.key, a["env_id"], label, a["seed"], success]
    row += [m[c] for c in COLUMNS[5:]]
    return {
        "policy": [format_row(row)],
        "paths": path_rows(episode.key, label, a["seed"], result),
        "vetoes": veto_rows(episode.key, label, a["seed"], result.veto_judgements),
    }


def summarize(csv_path: str | Path, vetoes_csv: str | Path | None = None) -> dict[str, dict[str, Any]]:
    """Per filter setting: episodes, success rate, entries, collisions (each rate of the four with
    its 95 % Wilson interval, ``goal_interval`` etc.), episodes that leaving the track ended, mean
    progress, distance driven, vetoes, veto events and false vetoes (and each
    per km driven), missed vetoes, the largest veto error (``max_veto_error_m``; None: no veto to
    judge), cost, steps, and the share of them that ended off the track. With the campaign's
    ``vetoes.csv``, also the median of every judged veto's error (``median_veto_error_m``; None:
    none judged, or no ``vetoes.csv`` given) and of the onset vetoes' alone, those that began a
    braking event (``median_onset_veto_error_m``).

    Raises:
        ConfigError: the CSV lacks columns of :data:`COLUMNS` (written by an older version).
    """
    out: dict[str, dict[str, Any]] = {}
    rows = read_csv(csv_path)
    missing = [c for c in COLUMNS if rows and c not in rows[0]]
    require(not missing, "csv_path", f"{csv_path} lacks the columns {missing}: written by an older version")
    for r in rows:
        s = out.setdefault(
            r["filter"],
            dict.fromkeys(SUMMED, 0.0),
        )
        s["episodes"] += 1
        s["successes"] += r["success"] == "1"
        s["goals"] += r["goal"] == "1"
        s["entries"] += r["entered"] == "1"
        s["collisions"] += r["collision"] == "1"
        s["left_track"] += r["left_track"] == "1"
        s["progress_m"] += float(r["progress_m"])
        s["distance_m"] += float(r["distance_m"])
        s["vetoes"] += int(r["vetoes"])
        s["veto_events"] += int(r["veto_events"])
        s["false_vetoes"] += int(r["false_vetoes"])
        s["missed_vetoes"] += int(r["missed_vetoes"])
        s["cost"] += float(r["cost"])
        s["steps"] += int(r["steps"])
        s["off_track_steps"] += int(r["off_track_steps"])
        s["stopped"] += r["stopped"] == "1"
        s["steered_steps"] += int(r["steered_steps"])
    for s in out.values():
        n = int(s["episodes"])
        for count, rate in (
            ("successes", "success"),
            ("goals", "goal"),
            ("entries", "entry"),
            ("collisions", "collision"),
        ):
            s[f"{rate}_rate"] = s[count] / n
            s[f"{rate}_interval"] = rate_interval(int(s[count]), n)
        s["mean_progress_m"] = s.pop("progress_m") / s["episodes"]
        km = s["distance_m"] / 1000.0
        s["vetoes_per_km"] = s["vetoes"] / km if km > 0 else 0.0
        s["veto_events_per_km"] = s["veto_events"] / km if km > 0 else 0.0
        s["false_vetoes_per_km"] = s["false_vetoes"] / km if km > 0 else 0.0
        s["off_track_share"] = s["off_track_steps"] / s["steps"] if s["steps"] > 0 else 0.0
    for name, s in out.items():
        errors = (float(r["max_veto_error_m"]) for r in rows if r["filter"] == name)
        s["max_veto_error_m"] = largest_veto_error_m(errors)
        s["median_veto_error_m"] = s["median_onset_veto_error_m"] = None
    if vetoes_csv is not None:
        errors, onsets = veto_errors_by(vetoes_csv, lambda r: r["filter"])
        for name, s in out.items():
            s["median_veto_error_m"] = median_or_none(errors.get(name, []))
            s["median_onset_veto_error_m"] = median_or_none(onsets.get(name, []))
    return out


def run_policy_campaign(
    config: PolicyCampaignConfig,
    out_dir: str | Path,
    options: RunOptions | None = None,
) -> tuple[Path, Path, dict[str, dict[str, Any]]]:
    """Run (or resume) it; returns the CSV, the summary JSON and the summary."""
    out = Path(out_dir)
    tables = {"policy": COLUMNS, "paths": PATH_COLUMNS, "vetoes": VETO_COLUMNS}
    csvs = run_campaign(run_episode, episodes(config), out, tables, options, "policy episodes")
    csv = csvs["policy"]
    summary = summarize(csv, csvs["vetoes"])
    text = json.dumps({"config": dataclasses.asdict(config), "summary": summary}, indent=1, sort_keys=True)
    return csv, write_text_atomic(out / "summary.json", text), summary
