"""``negobs policy``: the trained policies shipped with negobs_gym and their records.

``list`` prints each policy: a line with its name (what ``negobs eval policy`` and ``negobs train
--init`` take), the env and settings it was fitted on (which ``negobs eval policy NAME`` applies),
the algorithm and its steps and the recipe that recreates it; then, indented, its figures on
today's default detector grid from its record, with the grid, seeds and command they were
measured with. ``show NAME`` prints
the whole record as JSON: the commands that trained and evaluated it, wall times, and every
evaluation with its seeds; given a model file instead, it prints the env and ``--set`` that model
records (``negobs train`` saves them inside each zip), which ``negobs eval policy`` applies.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``policy`` command and its ``list`` and ``show`` subcommands."""
    parser = subparsers.add_parser(
        "policy",
        help="list the shipped trained policies, or show one's record (commands, evaluations)",
        description="The trained policies shipped in negobs_gym/drivers/trained: each a "
        "stable-baselines3 model (NAME.zip) and its record (NAME.json).",
    )
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    p_list = sub.add_parser(
        "list", help="name, env and settings, steps, recipe, and figures on today's default grid of each"
    )
    p_list.set_defaults(handler=_list)
    p_show = sub.add_parser("show", help="print a shipped policy's record, or a model file's, as JSON")
    p_show.add_argument(
        "name", metavar="NAME", help="shipped policy name (see 'negobs policy list') or a saved model"
    )
    p_show.set_defaults(handler=_show)


def summary_line(name: str, record: dict[str, Any]) -> str:
    """The first line of a policy in ``negobs policy list``: name, env with its settings (what
    ``negobs eval policy NAME`` applies), algorithm and steps (a behaviour clone has none), and
    the command that recreates it from its recipe."""
    from negobs_gym.spec.overrides import describe_overrides

    env = describe_overrides(str(record.get("env", "-")), tuple(record.get("set", ())))
    steps = int(record.get("steps", 0))
    trained = f"{record.get('algo', '-')} {steps:,} steps" if steps else "cloned, no RL step"
    return f"{name}  {env}  {trained}  recipe: {record.get('recipe', '-')}"


def figures_lines(record: dict[str, Any]) -> list[str]:
    """The lines under :func:`summary_line`: the policy's figures on today's default grid (its
    record's ``evaluation.default_grid``), without and behind the filter, each goal rate with its
    95 % Wilson interval, then the grid and seeds they were measured on and the command."""
    figures = record.get("evaluation", {}).get("default_grid")
    if not isinstance(figures, dict):
        return ["  default grid: not measured"]
    parts = []
    for key, label in (("nofilter", "no filter"), ("filter", "behind the filter")):
        result = figures.get(key)
        if isinstance(result, dict) and {"episodes", "goal"} <= result.keys():
            parts.append(f"{label}: {_result_text(result)}")
    seeds = figures.get("seeds", "-")
    return [
        f"  default grid, seeds {seeds}: " + ("; ".join(parts) or "-"),
        f"    grid: {figures.get('grid', '-')}",
        f"    command: {figures.get('command', '-')}",
    ]


def _result_text(result: dict[str, Any]) -> str:
    """``goal 15/20 (0.53-0.89), entries 1, collisions -``, and vetoes where recorded."""
    from negobs_gym.eval.stats import format_interval, rate_interval

    goals, episodes = int(result["goal"]), int(result["episodes"])
    text = (
        f"goal {goals}/{episodes} ({format_interval(rate_interval(goals, episodes))}), "
        f"entries {result.get('entries', '-')}, collisions {result.get('collisions', '-')}"
    )
    return text + (f", vetoes {result['vetoes']}" if "vetoes" in result else "")


def _list(args: argparse.Namespace) -> int:
    from negobs_gym.drivers.zoo import baseline_names, baseline_record

    for name in baseline_names():
        record = baseline_record(name)
        print("\n".join([summary_line(name, record), *figures_lines(record)]), file=sys.stdout)
    return 0


def _show(args: argparse.Namespace) -> int:
    from pathlib import Path

    from negobs_gym.drivers.zoo import baseline_record, fitted_on_record, recorded_env
    from negobs_gym.errors import ConfigError

    if Path(args.name).is_file() or Path(f"{args.name}.zip").is_file():
        recorded = recorded_env(args.name)
        if recorded is None:
            raise ConfigError("model_path", f"{args.name} holds no record of the env it was fitted on")
        record = fitted_on_record(*recorded)
    else:
        record = baseline_record(args.name)
    sys.stdout.write(json.dumps(record, indent=1, ensure_ascii=False) + "\n")
    return 0
