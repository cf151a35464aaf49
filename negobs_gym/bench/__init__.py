"""Benchmarks: four maintained suites, one runner, a JSON results file per run, and the docs'
figure tables generated from those files (``negobs bench``; benchmarks/README.md).

Suites: ``env`` (env throughput), ``detector`` (detector and ray-cast cost), ``detection``
(detection quality through the detection campaign of ``negobs eval detection``) and ``safety``
(braking behind the safety filter). Each is a module of this package with a ``SUITE``
(:class:`~negobs_gym.bench.harness.Suite`); they are imported by name when run, so reading or
writing tables imports no simulator.
"""

from __future__ import annotations

import importlib

from negobs_gym.bench.harness import (
    DEFAULT_OUT,
    BenchError,
    Clock,
    Figure,
    Suite,
    code_version,
    machine,
    read_results,
    results_path,
    run_suite,
)
from negobs_gym.bench.tables import fill_tables, format_value, markdown_files, write_tables

#: The suites in the order ``negobs bench`` runs them.
SUITE_NAMES: tuple[str, ...] = ("env", "detector", "detection", "safety")

__all__ = [
    "DEFAULT_OUT",
    "SUITE_NAMES",
    "BenchError",
    "Clock",
    "Figure",
    "Suite",
    "code_version",
    "fill_tables",
    "format_value",
    "load_suite",
    "machine",
    "markdown_files",
    "read_results",
    "results_path",
    "run_suite",
    "write_tables",
]


def load_suite(name: str) -> Suite:
    """The suite called ``name`` (its module imported now).

    Raises:
        BenchError: no suite has that name.
    """
    if name not in SUITE_NAMES:
        raise BenchError(f"unknown suite {name!r}; the suites: {', '.join(SUITE_NAMES)}")
    return importlib.import_module(f"negobs_gym.bench.{name}").SUITE
