"""A scenario run's results as CSV tables: what ``negobs scenario run --out DIR`` writes.

``results.csv`` has one row per seed (:data:`RESULT_COLUMNS`: the fields of
:class:`~negobs_gym.eval.scenario_runner.ScenarioResult`), ``vetoes.csv`` each veto and missed veto
(:data:`~negobs_gym.eval.vetoes.VETO_COLUMNS`, the campaigns' table), ``paths.csv`` the rear-axle
centre after the reset and after every step (:data:`PATH_COLUMNS`), and ``scenario.toml`` the spec
as it ran (every default filled in, driver and filter as chosen), which ``negobs scenario run
DIR/scenario.toml`` runs again. Rows come in seed order; floats are written with the campaigns'
fixed decimals (:func:`~negobs_gym.eval.campaign.format_value`), so the same seeds give the same
files whatever the worker count.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

from negobs_gym.core.files import write_text_atomic
from negobs_gym.errors import require
from negobs_gym.eval.campaign import format_row
from negobs_gym.eval.scenario_runner import ScenarioResult
from negobs_gym.eval.vetoes import VETO_COLUMNS, veto_rows
from negobs_gym.spec.scenario import ScenarioSpec, spec_to_toml

__all__ = ["PATH_COLUMNS", "RESULT_COLUMNS", "TABLE_FILES", "check_csv_text", "write_scenario_tables"]

#: ``results.csv``: one row per seed. ``passed`` = no criterion failed; ``failures`` and
#: ``termination`` are ``;``-separated names (empty: none); ``stop_margin_m`` and
#: ``max_veto_error_m`` are NaN where the result holds None; distances from the front bumper.
RESULT_COLUMNS = (
    "episode",
    "scenario",
    "seed",
    "driver",
    "filter",
    "passed",
    "failures",
    "task_done",
    "steps",
    "time_s",
    "entered",
    "stopped_before",
    "stop_margin_m",
    "start_gap_m",
    "collision",
    "trapped",
    "rollover",
    "goal",
    "left_track",
    "max_decel_mps2",
    "vetoes",
    "veto_events",
    "false_vetoes",
    "missed_vetoes",
    "max_veto_error_m",
    "positive_gap_m",
    "termination",
    "truncated",
)
#: ``paths.csv``: the rear-axle centre's world position at the reset (step 0) and after each step;
#: ``vetoed`` / ``missed_veto``: that step's action was vetoed / a missed veto.
PATH_COLUMNS = ("episode", "seed", "step", "x_m", "y_m", "vetoed", "missed_veto")
#: The files :func:`write_scenario_tables` writes into its folder.
TABLE_FILES = ("results.csv", "vetoes.csv", "paths.csv", "scenario.toml")


def check_csv_text(field: str, text: str) -> None:
    """Raise a ConfigError naming ``field`` when ``text`` (a scenario's or a policy's name) cannot
    stand in a CSV cell (a comma, quote or line break): a run with ``--out`` checks its names
    before its first episode."""
    require(
        not any(c in text for c in ',"\n\r'),
        field,
        f"must hold no comma, quote or line break to be written to CSV, got {text!r}",
    )


def _episode(result: ScenarioResult) -> str:
    """The episode's key in every table: ``<scenario>_seed<k>``, as ``--draw``'s and ``--video``'s files."""
    return f"{result.scenario}_seed{result.seed}"


def _filter_label(result: ScenarioResult) -> str:
    return "filter" if result.filtered else "nofilter"


def _result_row(r: ScenarioResult) -> str:
    def nan_if_none(value: float | None) -> float:
        return math.nan if value is None else value

    values = {
        "episode": _episode(r),
        "scenario": r.scenario,
        "seed": r.seed,
        "driver": r.driver,
        "filter": _filter_label(r),
        "passed": r.passed,
        "failures": ";".join(r.failures),
        "task_done": r.task_done,
        "steps": r.steps,
        "time_s": r.time_s,
        "entered": r.entered_negative_obstacle,
        "stopped_before": r.stopped_before,
        "stop_margin_m": nan_if_none(r.stop_margin_m),
        "start_gap_m": r.start_gap_m,
        "collision": r.collision,
        "trapped": r.trapped,
        "rollover": r.rollover,
        "goal": r.goal_reached,
        "left_track": r.left_track,
        "max_decel_mps2": r.max_decel_mps2,
        "vetoes": r.vetoes,
        "veto_events": r.veto_events,
        "false_vetoes": r.false_vetoes,
        "missed_vetoes": r.missed_vetoes,
        "max_veto_error_m": nan_if_none(r.max_veto_error_m),
        "positive_gap_m": r.positive_gap_m,
        "termination": ";".join(r.termination),
        "truncated": r.truncated,
    }
    return format_row(values[c] for c in RESULT_COLUMNS)


def _path_rows(r: ScenarioResult) -> list[str]:
    vetoed, missed = set(r.vetoed_steps), set(r.missed_steps)
    return [
        format_row([_episode(r), r.seed, step, x, y, step in vetoed, step in missed])
        for step, (x, y) in enumerate(r.path_xy_m)
    ]


def _csv(columns: Iterable[str], rows: Iterable[str]) -> str:
    return "\n".join([",".join(columns), *rows]) + "\n"


def write_scenario_tables(
    out_dir: str | Path, spec: ScenarioSpec, results: Iterable[ScenarioResult]
) -> list[Path]:
    """Write :data:`TABLE_FILES` for ``results`` (of ``spec``, in the order given) into ``out_dir``,
    each atomically (a file already there is replaced whole); returns their paths.

    Raises:
        ConfigError: the scenario's or a driver's name cannot stand in a CSV cell
            (:func:`check_csv_text`), before anything is written.
    """
    results = list(results)
    check_csv_text("name", spec.name)
    for r in results:
        check_csv_text("driver", r.driver)
    out = Path(out_dir)
    tables = {
        "results.csv": _csv(RESULT_COLUMNS, (_result_row(r) for r in results)),
        "vetoes.csv": _csv(
            VETO_COLUMNS,
            (
                row
                for r in results
                for row in veto_rows(_episode(r), _filter_label(r), r.seed, r.veto_judgements)
            ),
        ),
        "paths.csv": _csv(PATH_COLUMNS, (row for r in results for row in _path_rows(r))),
        "scenario.toml": spec_to_toml(spec),
    }
    return [write_text_atomic(out / name, text) for name, text in tables.items()]
