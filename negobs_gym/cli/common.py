"""Argument types and option groups shared by several ``negobs`` commands."""

from __future__ import annotations

import argparse
import os
import uuid
from collections.abc import Callable
from pathlib import Path


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0 (seeds, counts)."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 (workers, frames)."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def write_atomic(path: Path, write: Callable[[Path], object]) -> None:
    """Create ``path`` atomically: ``write(tmp)`` fills a temp file in the same folder, then
    ``os.replace`` puts it in place (readers never see a partial file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def add_set_option(parser: argparse.ArgumentParser) -> None:
    """``--set KEY.PATH=VALUE`` (repeatable): change one setting of the scenario (docs/scenarios.md)."""
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change one setting of the scenario, repeatable: observation.tighten_pairs=true, "
        "episode.time_limit_s=30, obstacles.0.depth_m=1.2; VALUE is TOML, or else text",
    )


def env_with_overrides(env: str, overrides: list[str], out_dir: str | Path, *, replace: bool = False) -> str:
    """``env`` itself without ``--set``; otherwise its scenario with the changes, written to
    ``OUT/scenario.toml`` (atomically; it records what ran), whose path runs in its place.

    Raises:
        ConfigError: ``OUT/scenario.toml`` holds another scenario (an earlier run's, which a
            resumed run would go on with) and ``replace`` is false.
    """
    if not overrides:
        return env
    from negobs_gym.errors import ConfigError
    from negobs_gym.scenarios import spec_to_toml
    from negobs_gym.scenarios.overrides import apply_overrides, spec_for_env

    text = spec_to_toml(apply_overrides(spec_for_env(env), overrides))
    path = Path(out_dir) / "scenario.toml"
    if path.is_file() and path.read_text(encoding="utf-8") != text and not replace:
        raise ConfigError(
            "--set", f"{path} holds an earlier run's other scenario: use its settings or another --out"
        )
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return str(path)
