"""Argument types and option groups shared by several ``negobs`` commands."""

from __future__ import annotations

import argparse
import math
from typing import Any


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


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0 (heights, resolutions, distances)."""
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0 (tolerances, gaps)."""
    value = float(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def add_set_option(parser: argparse.ArgumentParser) -> None:
    """``--set KEY.PATH=VALUE`` (repeatable): change one setting of the scenario (docs/scenarios.md)."""
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change one setting of the scenario, repeatable: observation.tighten_pairs=false, "
        "episode.time_limit_s=30, obstacles.0.depth_m=1.2; VALUE is TOML, or else text",
    )


def add_runner_options(group: argparse._ArgumentGroup, unit: str) -> None:
    """``--workers``, ``--ray`` and ``--resume`` of a command driven by the campaign runner
    (:mod:`negobs_gym.eval.campaign`); ``unit`` names what a resumed run keeps (``episodes``)."""
    group.add_argument("--workers", type=positive_int, default=1, help="local worker processes (default: 1)")
    group.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help="run on Ray (pip install 'negobs_gym[ray]'); no ADDRESS starts a local instance",
    )
    group.add_argument("--resume", action="store_true", help=f"keep finished {unit} of a killed run")


def task_env_or_exit(
    parser: argparse.ArgumentParser, env: str, source: str | None, overrides: list[str]
) -> Any:
    """:func:`~negobs_gym.envs.make_env` of a command's ``--env``, ``--source`` and ``--set``;
    a bad one exits 2 through ``parser.error``, naming the field."""
    from negobs_gym.envs import make_env, source_overrides
    from negobs_gym.errors import ConfigError

    try:
        return make_env(env, [*source_overrides(source), *overrides])
    except ConfigError as error:
        parser.error(str(error))
