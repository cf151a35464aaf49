"""Videos of a campaign's episodes, replayed from the arguments they ran with and checked against
the rows they wrote.

An episode depends only on the arguments its campaign gave it (model, env or scenario, grid
source, rig, filter, seed; docs/determinism.md), and a policy or braking campaign keeps them with
the episode's rows in ``parts/<key>.json``. :func:`replay_videos` runs the episode again from them
with the env's frames written to an MP4, and compares every row the replay gives (the episode
table's line and each ``paths.csv`` line, as text) with the recorded ones: the video is of the
episode in the tables, or the replay raises (a changed model file, package version or setting)
and leaves no video.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

from negobs_gym.drivers.zoo import resolve_model
from negobs_gym.errors import NegobsError, require
from negobs_gym.eval import braking_campaign, policy_campaign
from negobs_gym.eval.campaign import PARTS_DIR, Episode, Rows
from negobs_gym.eval.paths import chosen_episodes
from negobs_gym.spec.overrides import recorded_env_in

__all__ = ["ReplayMismatch", "replay_videos"]


class ReplayMismatch(NegobsError, RuntimeError):
    """A replayed episode's rows differ from the campaign's: the video would show another episode."""


def _episode_runner(folder: Path) -> Callable[[Episode], Rows]:
    """The campaign's episode function: a policy campaign's or a braking campaign's."""
    return (policy_campaign if (folder / "policy.csv").is_file() else braking_campaign).run_episode


def _first_difference(replayed: list[str], recorded: list[str]) -> int:
    """Index of the first row that differs (or the shorter length)."""
    pairs = zip(replayed, recorded, strict=False)
    return next((k for k, (a, b) in enumerate(pairs) if a != b), min(len(replayed), len(recorded)))


def replay_videos(
    campaign_dir: str | Path,
    keys: Sequence[str] = (),
    *,
    everything: bool = False,
    limit: int | None = None,
    out_dir: str | Path | None = None,
    model: str | Path | None = None,
) -> list[Path]:
    """Replay episodes of a ``negobs eval policy|braking --out`` folder into ``<out_dir>/<key>.mp4``.

    Args:
        keys: the episodes (the episode table's ``episode`` column); empty: those that did not do
            their task, or all of them with ``everything`` (as :func:`~negobs_gym.eval.paths.
            draw_paths` chooses).
        limit: replay at most this many (in key order).
        out_dir: the videos' folder (default ``campaign_dir/videos``).
        model: the model the episodes ran, where it lies now (a saved model moved since, or a
            folder copied to another machine; the record keeps the path it was given). The replay
            is still checked against the record, so another model is refused as a mismatch.

    Returns:
        The MP4s written, in key order.

    Raises:
        ConfigError: not a policy or braking campaign's folder (field ``campaign_dir``), an unknown
            key (``keys``), an episode whose part does not record its arguments (a campaign
            from before they were recorded), no model at ``model``, or ``model`` given for an
            episode of a scripted driver (field ``model``).
        ReplayMismatch: a replay's rows differ from the campaign's; its video is removed.
    """
    if model is not None:
        model = resolve_model(str(model), "model")
    folder = Path(campaign_dir)
    _, chosen = chosen_episodes(folder, keys, everything=everything, limit=limit)
    run_episode = _episode_runner(folder)
    out = Path(out_dir) if out_dir is not None else folder / "videos"
    written = []
    for key in chosen:
        part = folder / PARTS_DIR / f"{key}.json"
        record = json.loads(part.read_text(encoding="utf-8")) if part.is_file() else {}
        require("args" in record, key, f"{part} does not record the episode's arguments: rerun the campaign")
        args = dict(record["args"])
        if "env_id" in args:  # a policy episode: its --set scenario as it can be found now
            args["env_id"] = recorded_env_in(args["env_id"], folder)
        if model is not None:
            require(
                args.get("model_path") is not None, "model", f"episode {key} ran a scripted driver, no model"
            )
            args["model_path"] = model
        video = out / f"{key}.mp4"
        replayed = run_episode(Episode(key, {**args, "video_to": video}))
        for table, recorded in sorted(record["rows"].items()):
            if replayed.get(table) != recorded:
                video.unlink(missing_ok=True)
                raise ReplayMismatch(
                    f"episode {key}: the replay's {table}.csv rows differ from the campaign's at row "
                    f"{_first_difference(replayed.get(table, []), recorded)} (model file, package "
                    "version or settings changed since the campaign ran)"
                )
        written.append(video)
    return written
