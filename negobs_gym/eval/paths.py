"""Where a campaign's drives went: each evaluated episode's path drawn over its terrain.

``negobs eval policy`` and ``negobs eval braking`` write ``paths.csv`` beside their episode table
(``policy.csv``, ``braking.csv``; :data:`~negobs_gym.eval.braking_campaign.PATH_COLUMNS`: the
car's pose and speed at the reset and after every step). :func:`draw_paths` rebuilds each chosen
episode's terrain from its env or scenario and seed (the terrain depends on nothing else) and
writes ``<key>.png``: the terrain with the ground-truth obstacles, the path (yellow), the car where
the episode ended (orange), the steps the safety filter vetoed (magenta dots), the steps it let
through with a true hazard well inside R(v) (cyan crosses, missed vetoes) and a caption with
the outcome. By default it draws the episodes that did not do their task (no goal; for braking, no
stop before the obstacle, or a veto on the obstacle-free track), the ones to look at.
"""

from __future__ import annotations

import json
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.envs import make_env
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.braking_campaign import PATH_COLUMNS, episode_overrides, obstacle_free, scene_name
from negobs_gym.eval.campaign import PARTS_DIR, read_csv
from negobs_gym.sim.render import render_drive
from negobs_gym.spec import recorded_env_in

__all__ = ["chosen_episodes", "draw_paths", "episode_outcome", "task_done"]

#: The failure columns of the episode tables, in the order a caption names them.
OUTCOMES = ("entered", "collision", "rollover", "trapped", "left_track")
#: The episode table of each campaign that records paths.
EPISODE_TABLES = ("policy", "braking")


def _is_braking(row: dict[str, str]) -> bool:
    return "scenario" in row


def episode_outcome(row: dict[str, str]) -> str:
    """How a ``policy.csv`` or ``braking.csv`` episode ended, in words: a failure, ``goal`` or
    ``no goal`` (policy), ``stopped`` or ``drove on`` (braking)."""
    failures = [name for name in OUTCOMES if row.get(name) == "1"]
    if failures:
        return " + ".join(failures)
    if _is_braking(row):
        return "stopped" if row["stopped"] == "1" else "drove on"
    return "goal" if row["goal"] == "1" else "no goal"


def task_done(row: dict[str, str]) -> bool:
    """Whether an episode did its task: the goal (policy); braking: stopped short of the obstacle
    without entering it, or on the obstacle-free track no failure and no veto."""
    if not _is_braking(row):
        return row["goal"] == "1"
    failed = any(row[name] == "1" for name in OUTCOMES if name in row)
    if obstacle_free(row["scenario"]):  # any veto is a false one
        return not failed and row["vetoes"] == "0"
    return not failed and row["stopped"] == "1"


def _recorded_args(folder: Path, key: str) -> dict[str, Any]:
    """The arguments an episode ran with, as its part records them (empty: no part)."""
    part = folder / PARTS_DIR / f"{key}.json"
    return dict(json.loads(part.read_text(encoding="utf-8")).get("args", {})) if part.is_file() else {}


def _terrain_and_caption(row: dict[str, str], folder: Path) -> tuple[Any, str]:
    """The episode's terrain, rebuilt from its env or scenario, the campaign's overrides and its
    seed on the oracle grid (the terrain is the seed's whatever the grid; the oracle spares the
    detector's set-up), and its caption."""
    args = _recorded_args(folder, row["episode"])
    if _is_braking(row):
        overrides = [*episode_overrides({**args, "driver": row["driver"]}), "observation.source=oracle"]
        env = make_env(scene_name(row["scenario"]), overrides)
        name = f"{row['scenario']} seed {row['seed']} {row['driver']}, {row['filter']}"
        result = f"gap {float(row['final_gap_m']):.2f} m"
    else:
        overrides = [*args.get("overrides", ()), "observation.source=oracle"]
        env = make_env(recorded_env_in(row["env"], folder), overrides)
        shown = env.unwrapped.scenario.name if row["env"].endswith(".toml") else row["env"]
        name = f"{shown} seed {row['seed']} {row['filter']}"
        result = f"{float(row['progress_m']):.1f} m"
    env.reset(seed=int(row["seed"]))
    terrain = env.unwrapped.terrain
    env.close()
    return terrain, f"{name}: {episode_outcome(row)}, {result}, {row['vetoes']} vetoes"


def chosen_episodes(
    folder: Path, keys: Sequence[str], *, everything: bool, limit: int | None
) -> tuple[dict[str, dict[str, str]], list[str]]:
    """A policy or braking campaign's episode rows by key, and the keys chosen from them: ``keys``,
    or where empty those that did not do their task (all with ``everything``), at most ``limit``,
    in key order.

    Raises:
        ConfigError: no ``policy.csv`` or ``braking.csv`` and ``paths.csv`` in ``folder`` (field
            ``campaign_dir``) or an unknown key (``keys``).
    """
    table = next((folder / f"{n}.csv" for n in EPISODE_TABLES if (folder / f"{n}.csv").is_file()), None)
    if table is None:
        raise ConfigError(
            "campaign_dir",
            f"no policy.csv or braking.csv in {folder}: not a `negobs eval policy|braking --out` folder",
        )
    paths_csv = folder / "paths.csv"
    require(paths_csv.is_file(), "campaign_dir", f"no paths.csv in {folder}: a campaign from before paths")
    episodes = {r["episode"]: r for r in read_csv(table)}
    unknown = sorted(set(keys) - set(episodes))
    require(not unknown, "keys", f"no episodes {unknown} in {table}")
    default = sorted(k for k, r in episodes.items() if everything or not task_done(r))
    chosen = sorted(keys) if keys else default
    return episodes, chosen[:limit] if limit is not None else chosen


def draw_paths(
    campaign_dir: str | Path,
    keys: Sequence[str] = (),
    *,
    everything: bool = False,
    limit: int | None = None,
    out_dir: str | Path | None = None,
    zoom_m: float | None = None,
) -> list[Path]:
    """Draw episodes of a policy or braking campaign to ``out_dir`` (default ``campaign_dir/paths``).

    Args:
        keys: the episodes (the episode table's ``episode`` column); empty: those that did not do
            their task (:func:`task_done`), or all of them with ``everything``.
        limit: draw at most this many (in key order).
        zoom_m: draw only the square of this half-width around where each drive ended [m]; None:
            the whole terrain.

    Returns:
        The PNGs written, in key order.

    Raises:
        ConfigError: no ``policy.csv`` or ``braking.csv`` and ``paths.csv`` in ``campaign_dir``
            (field ``campaign_dir``), an unknown key (``keys``), or an episode without path rows
            (a campaign from before paths were recorded).
    """
    folder = Path(campaign_dir)
    episodes, chosen = chosen_episodes(folder, keys, everything=everything, limit=limit)
    paths_csv = folder / "paths.csv"
    points: dict[str, list[list[float]]] = defaultdict(list)
    for row in read_csv(paths_csv):
        if row["episode"] in chosen:
            row.setdefault("missed_veto", "0")  # a campaign from before missed vetoes were counted
            points[row["episode"]].append([float(row[c]) for c in PATH_COLUMNS[4:]])
    out = Path(out_dir) if out_dir is not None else folder / "paths"
    written = []
    for key in chosen:
        if not points[key]:
            raise ConfigError(key, f"no rows in {paths_csv}: a campaign from before paths were recorded")
        terrain, caption = _terrain_and_caption(episodes[key], folder)
        x, y, yaw, _, vetoed, missed = np.asarray(points[key]).T
        path = out / f"{key}.png"
        render_drive(terrain, np.column_stack([x, y]), yaw[-1], vetoed > 0, caption, path, zoom_m, missed > 0)
        written.append(path)
    return written
