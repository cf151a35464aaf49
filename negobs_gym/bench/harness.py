"""The benchmark runner: figures, suites, timers and the JSON results file of a suite run.

A suite is a list of measurements, each a function of the suite's size (a frozen dataclass of
counts: frames, steps, seeds) that returns named :class:`Figure` s. :meth:`Suite.run` runs them
under one progress line; :func:`run_suite` times the whole run (wall and CPU, peak resident
memory), adds the code version and the machine, and writes ``SUITE.json`` (``SUITE.quick.json``
for a quick run, so a quick run never replaces the full figures) atomically.
"""

from __future__ import annotations

import dataclasses
import json
import math
import resource
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from negobs_gym.core.files import write_text_atomic
from negobs_gym.core.provenance import code_version, machine
from negobs_gym.errors import ConfigError, NegobsError

__all__ = [
    "DEFAULT_OUT",
    "BenchError",
    "Clock",
    "Figure",
    "Suite",
    "code_version",
    "machine",
    "median_ms",
    "peak_rss_mb",
    "positive_counts",
    "read_results",
    "results_path",
    "run_suite",
]

#: Where ``negobs bench`` writes its JSON files and ``negobs bench --tables`` reads them.
DEFAULT_OUT = Path("benchmarks/results")


class BenchError(NegobsError, ValueError):
    """A benchmark figure, results file or generated-table block cannot be used as given."""


@dataclass(frozen=True)
class Figure:
    """One measured figure: a finite ``value`` in ``unit`` (``""``: a plain number) and ``what`` it
    is, in a few words (the docs' tables print it)."""

    value: float
    unit: str
    what: str

    def __post_init__(self) -> None:
        value = float(self.value)
        if not math.isfinite(value):
            raise BenchError(f"figure {self.what!r}: its value must be finite, got {self.value!r}")
        object.__setattr__(self, "value", value)


Figures = dict[str, Figure]
Measurement = Callable[[Any], Figures]


def positive_counts(size: Any) -> None:
    """Raise :class:`~negobs_gym.errors.ConfigError` unless every field of the size dataclass
    ``size`` is a number >= 1 (a suite's sizes are counts: steps, frames, seeds, repeats)."""
    for f in dataclasses.fields(size):
        value = getattr(size, f.name)
        if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 1:
            raise ConfigError(f.name, f"must be a number >= 1, got {value!r}")


@dataclass(frozen=True)
class Suite:
    """A named list of measurements and the sizes it runs at: ``full`` (figures for the docs) and
    ``quick`` (every suite together within minutes)."""

    name: str
    what: str
    full: Any
    quick: Any
    measurements: tuple[Measurement, ...]

    def run(self, quick: bool = False, size: Any = None, progress: bool = True) -> Figures:
        """Every measurement's figures; ``size`` (an instance of the suite's size dataclass, for
        tests) replaces the ``quick`` / ``full`` sizes.

        Raises:
            BenchError: ``size`` is of another type, or two measurements give the same key.
        """
        if size is None:
            size = self.quick if quick else self.full
        elif type(size) is not type(self.full):
            raise BenchError(f"suite {self.name}: size must be a {type(self.full).__name__}, got {size!r}")
        figures: Figures = {}
        with tqdm(self.measurements, desc=f"bench {self.name}", unit="part", disable=not progress) as bar:
            for measure in bar:
                bar.set_postfix_str(measure.__name__)
                got = measure(size)
                if figures.keys() & got.keys():
                    raise BenchError(
                        f"suite {self.name}: keys given twice: {sorted(figures.keys() & got.keys())}"
                    )
                figures.update(got)
        return figures


class Clock:
    """Wall and CPU seconds of the ``with`` blocks it times, summed over blocks (time the steps of
    a loop, not its resets). CPU is every thread of this process plus the child processes that
    ended inside the blocks (vector-env workers, campaign workers)."""

    def __init__(self) -> None:
        self.wall_s = 0.0
        self.cpu_s = 0.0
        self.blocks = 0

    def __enter__(self) -> Clock:
        self._wall, self._cpu = time.perf_counter(), _cpu_s()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall_s += time.perf_counter() - self._wall
        self.cpu_s += _cpu_s() - self._cpu
        self.blocks += 1

    def rate(self, count: float) -> float:
        """``count`` over the wall seconds: things per second."""
        return count / self.wall_s


def _cpu_s() -> float:
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def median_ms(seconds: list[float]) -> float:
    """The median of ``seconds`` in milliseconds."""
    return 1e3 * float(np.median(seconds))


def peak_rss_mb() -> float:
    """The largest resident memory of this process, or of one of its ended children, so far [MiB]."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(own, child) / 1024.0  # Linux reports KiB


def results_path(out_dir: str | Path, suite: str, quick: bool) -> Path:
    """``out_dir/SUITE.json``, or ``SUITE.quick.json`` for a quick run."""
    return Path(out_dir) / f"{suite}{'.quick' if quick else ''}.json"


def run_suite(
    suite: Suite,
    quick: bool = False,
    out_dir: str | Path = DEFAULT_OUT,
    size: Any = None,
    progress: bool = True,
) -> tuple[Path, dict[str, Any]]:
    """Run ``suite`` and write its results file; the file's path and its content.

    The file holds ``suite``, ``quick``, ``code_version``, ``machine``, the run's ``wall_s``,
    ``cpu_s`` and ``peak_rss_mb``, and ``figures`` (key -> ``value``, ``unit``, ``what``).
    """
    with Clock() as clock:
        figures = suite.run(quick, size, progress)
    results = {
        "suite": suite.name,
        "quick": bool(quick),
        "code_version": code_version(),
        "machine": machine(),
        "wall_s": round(clock.wall_s, 3),
        "cpu_s": round(clock.cpu_s, 3),
        "peak_rss_mb": round(peak_rss_mb(), 1),
        "figures": {key: dataclasses.asdict(figure) for key, figure in figures.items()},
    }
    path = results_path(out_dir, suite.name, quick)
    write_text_atomic(path, json.dumps(results, indent=1) + "\n")
    return path, results


def read_results(path: str | Path) -> Mapping[str, Any]:
    """A results file's content.

    Raises:
        BenchError: it is not JSON with a ``figures`` mapping.
    """
    try:
        results = json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise BenchError(f"{path}: not a results file ({error})") from error
    if not isinstance(results, dict) or not isinstance(results.get("figures"), dict):
        raise BenchError(f"{path}: not a results file (no 'figures' mapping)")
    return results
