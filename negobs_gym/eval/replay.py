"""Videos of a policy campaign's episodes, replayed from their seeds and checked against the record.

An episode depends only on its seed, the model and the settings the campaign recorded
(``summary.json``'s config, the row's env and filter; docs/determinism.md), so it can be run again
with the env's frames written to an MP4 instead of keeping frames for every episode of a campaign.
:func:`replay_videos` checks each replay against the campaign's own rows (the episode's
``policy.csv`` line and every ``paths.csv`` line, as text): the video is of the episode in the
table, or the replay raises (a changed model file, package version or setting) and leaves no video.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from negobs_gym.errors import NegobsError, require
from negobs_gym.eval.campaign import Episode
from negobs_gym.eval.paths import chosen_episodes

__all__ = ["ReplayMismatch", "replay_videos"]


class ReplayMismatch(NegobsError, RuntimeError):
    """A replayed episode's rows differ from the campaign's: the video would show another episode."""


def _lines_of(csv_path: Path, key: str) -> list[str]:
    """The lines of ``csv_path`` whose first column is ``key``, as written."""
    lines = csv_path.read_text(encoding="utf-8").splitlines()[1:]
    return [line for line in lines if line.split(",", 1)[0] == key]


def replay_videos(
    campaign_dir: str | Path,
    keys: Sequence[str] = (),
    *,
    everything: bool = False,
    limit: int | None = None,
    out_dir: str | Path | None = None,
) -> list[Path]:
    """Replay episodes of a ``negobs eval policy --out`` folder into ``<out_dir>/<key>.mp4``.

    Args:
        keys: the episodes (``policy.csv``'s ``episode`` column); empty: those that did not do
            their task, or all of them with ``everything`` (as :func:`~negobs_gym.eval.paths.
            draw_paths` chooses).
        limit: replay at most this many (in key order).
        out_dir: the videos' folder (default ``campaign_dir/videos``).

    Returns:
        The MP4s written, in key order.

    Raises:
        ConfigError: not a policy campaign's folder with its ``summary.json`` (field
            ``campaign_dir``) or an unknown key (``keys``).
        ReplayMismatch: a replay's rows differ from the campaign's; its video is removed.
    """
    from negobs_gym.eval.policy_campaign import run_episode
    from negobs_gym.scenarios.overrides import recorded_env_in

    folder = Path(campaign_dir)
    episodes, chosen = chosen_episodes(folder, keys, everything=everything, limit=limit)
    policy_csv, summary = folder / "policy.csv", folder / "summary.json"
    require(
        policy_csv.is_file() and summary.is_file(),
        "campaign_dir",
        f"no policy.csv and summary.json in {folder}: videos replay `negobs eval policy --out` folders",
    )
    config = json.loads(summary.read_text(encoding="utf-8"))["config"]
    out = Path(out_dir) if out_dir is not None else folder / "videos"
    written = []
    for key in chosen:
        row = episodes[key]
        video = out / f"{key}.mp4"
        args = {
            "model_path": config["model_path"],
            "env_id": recorded_env_in(row["env"], folder),
            "algo": config["algo"],
            "source": config["source"],
            "stop_for_positive": config["stop_for_positive"],
            "filtered": row["filter"] != "nofilter",
            "seed": int(row["seed"]),
            "video_to": video,
        }
        replayed = run_episode(Episode(key, args))
        for table, csv_path in (("policy", policy_csv), ("paths", folder / "paths.csv")):
            recorded = _lines_of(csv_path, key)
            if replayed[table] != recorded:
                video.unlink(missing_ok=True)
                step = next(
                    (k for k, (a, b) in enumerate(zip(replayed[table], recorded, strict=False)) if a != b),
                    min(len(recorded), len(replayed[table])),
                )
                raise ReplayMismatch(
                    f"episode {key}: the replay's {csv_path.name} rows differ from the campaign's at row "
                    f"{step} (model file, package version or settings changed since the campaign ran)"
                )
        written.append(video)
    return written
