"""Where a policy's drives went: each evaluated episode's path drawn over its terrain.

``negobs eval policy`` writes ``paths.csv`` beside ``policy.csv`` (:data:`PATH_COLUMNS`: the car's
pose and speed at the reset and after every step). :func:`draw_paths` rebuilds each chosen
episode's terrain from its env and seed (the terrain depends on nothing else) and writes
``<key>.png``: the terrain with the ground-truth obstacles, the path (yellow), the car where the
episode ended (orange), the steps the safety filter vetoed (magenta dots) and a caption with the
outcome. By default it draws the episodes that did not reach the goal, the ones to look at.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.campaign import read_csv
from negobs_gym.eval.policy_campaign import PATH_COLUMNS

__all__ = ["draw_paths", "episode_outcome"]

#: The failure columns of ``policy.csv``, in the order a caption names them.
OUTCOMES = ("entered", "collision", "rollover", "trapped", "left_track")


def episode_outcome(row: dict[str, str]) -> str:
    """How a ``policy.csv`` episode ended, in words: ``goal``, a failure, or ``no goal``."""
    failures = [name for name in OUTCOMES if row[name] == "1"]
    if failures:
        return " + ".join(failures)
    return "goal" if row["goal"] == "1" else "no goal"


def draw_paths(
    campaign_dir: str | Path,
    keys: Sequence[str] = (),
    *,
    everything: bool = False,
    limit: int | None = None,
    out_dir: str | Path | None = None,
    zoom_m: float | None = None,
) -> list[Path]:
    """Draw episodes of a policy campaign to ``out_dir`` (default ``campaign_dir/paths``).

    Args:
        keys: the episodes (``policy.csv``'s ``episode`` column); empty: those without a goal, or
            all of them with ``everything``.
        limit: draw at most this many (in key order).
        zoom_m: draw only the square of this half-width around where each drive ended [m]; None:
            the whole terrain.

    Returns:
        The PNGs written, in key order.

    Raises:
        ConfigError: no ``policy.csv`` / ``paths.csv`` in ``campaign_dir`` (field ``campaign_dir``),
            an unknown key (``keys``), or an episode without path rows (a campaign from before
            paths were recorded).
    """
    from negobs_gym.policies.training import make_task_env
    from negobs_gym.scenarios.overrides import recorded_env_in
    from negobs_gym.sim.render import render_drive

    folder = Path(campaign_dir)
    files = {name: folder / f"{name}.csv" for name in ("policy", "paths")}
    for path in files.values():
        require(
            path.is_file(),
            "campaign_dir",
            f"no {path.name} in {folder}: not a `negobs eval policy --out` folder",
        )
    episodes = {r["episode"]: r for r in read_csv(files["policy"])}
    unknown = sorted(set(keys) - set(episodes))
    require(not unknown, "keys", f"no episodes {unknown} in {files['policy']}")
    default = sorted(k for k, r in episodes.items() if everything or r["goal"] != "1")
    chosen = sorted(keys) if keys else default
    chosen = chosen[:limit] if limit is not None else chosen
    points: dict[str, list[list[float]]] = defaultdict(list)
    for row in read_csv(files["paths"]):
        if row["episode"] in chosen:
            points[row["episode"]].append([float(row[c]) for c in PATH_COLUMNS[4:]])
    out = Path(out_dir) if out_dir is not None else folder / "paths"
    written = []
    for key in chosen:
        if not points[key]:
            raise ConfigError(key, f"no rows in {files['paths']}: a campaign from before paths were recorded")
        row = episodes[key]
        # the terrain is the seed's whatever the grid: the oracle grid spares the detector's set-up
        env = make_task_env(recorded_env_in(row["env"], folder), "oracle")
        env.reset(seed=int(row["seed"]))
        terrain, scenario = env.unwrapped.terrain, env.unwrapped.scenario.name
        env.close()
        x, y, yaw, _, vetoed = np.asarray(points[key]).T
        name = scenario if row["env"].endswith(".toml") else row["env"]
        progress = float(row["progress_m"])
        caption = f"{name} seed {row['seed']} {row['filter']}: {episode_outcome(row)}, {progress:.1f} m"
        caption += f", {row['vetoes']} vetoes"
        path = out / f"{key}.png"
        render_drive(terrain, np.column_stack([x, y]), yaw[-1], vetoed > 0, caption, path, zoom_m)
        written.append(path)
    return written
