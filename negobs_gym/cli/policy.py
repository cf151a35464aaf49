"""``negobs policy``: the trained policies shipped with negobs_gym and their records.

``list`` prints one line per policy: its name (what ``negobs eval policy`` and ``negobs train
--init`` take), the env and settings it was fitted on (which ``negobs eval policy NAME`` applies),
the algorithm and its steps, and its recorded evaluation without the filter. ``show NAME`` prints
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
    p_list = sub.add_parser("list", help="name, env and settings, steps and recorded evaluation of each")
    p_list.set_defaults(handler=_list)
    p_show = sub.add_parser("show", help="print a shipped policy's record, or a model file's, as JSON")
    p_show.add_argument(
        "name", metavar="NAME", help="shipped policy name (see 'negobs policy list') or a saved model"
    )
    p_show.set_defaults(handler=_show)


def summary_line(name: str, record: dict[str, Any]) -> str:
    """One line of ``negobs policy list``: name, env with its settings, algorithm and steps (a
    behaviour clone has none), and the recorded evaluation without the filter, the goal rate with
    its 95 % Wilson interval (``-`` where the record has none)."""
    from negobs_gym.spec.overrides import describe_overrides

    env = describe_overrides(str(record.get("env", "-")), tuple(record.get("set", ())))
    steps = int(record.get("steps", 0))
    trained = f"{record.get('algo', '-')} {steps:,} steps" if steps else "cloned, no RL step"
    result = record.get("evaluation", {}).get("nofilter")
    if isinstance(result, dict) and {"episodes", "goal"} <= result.keys():
        from negobs_gym.eval.stats import format_interval, rate_interval

        goals, episodes = int(result["goal"]), int(result["episodes"])
        measured = (
            f"goal {goals}/{episodes} ({format_interval(rate_interval(goals, episodes))}), "
            f"entries {result.get('entries', '-')}, collisions {result.get('collisions', '-')} (no filter)"
        )
    else:
        measured = "-"
    return f"{name}  {env}  {trained}  {measured}"


def _list(args: argparse.Namespace) -> int:
    from negobs_gym.drivers.zoo import baseline_names, baseline_record

    for name in baseline_names():
        print(summary_line(name, baseline_record(name)), file=sys.stdout)
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
