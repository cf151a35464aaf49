"""The docs' figure tables, generated from the suites' results files.

A markdown file holds a block per table::

    <!-- bench-table: SUITE key1,key2 -->
    | figure | value | command |
    |---|---|---|
    | ... |
    <!-- /bench-table -->

:func:`fill_tables` rewrites each block's rows from ``SUITE.json`` (or, where only a quick run
exists, ``SUITE.quick.json``): one row per key, in the marker's order (no keys: every figure of
the suite, in the file's order), with the figure's ``what``, its value and unit, and the command
that measures it. A key ``OTHER.key`` takes its figure from suite ``OTHER``, so one table can show
figures of several suites (the README's headline table). Running it twice changes nothing.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from negobs_gym.bench.harness import BenchError, read_results, results_path
from negobs_gym.core.files import write_text_atomic

__all__ = ["fill_tables", "format_value", "markdown_files", "write_tables"]

_BLOCK = re.compile(
    r"(?P<open><!--[ \t]*bench-table:[ \t]*(?P<suite>[\w-]+)(?P<keys>[^>]*?)[ \t]*-->)"
    r"(?P<body>.*?)(?P<close><!--[ \t]*/bench-table[ \t]*-->)",
    re.DOTALL,
)
_OPEN = re.compile(r"<!--[ \t]*bench-table:")
HEADER = "| figure | value | command |\n|---|---|---|"


def format_value(value: float, unit: str) -> str:
    """``value`` to 3 significant digits (all of its integer digits, thousands separated), then
    ``unit``: ``34.9 steps/s``, ``0.083 s``, ``1,235 steps/s``, ``0``."""
    if value == 0:
        text = "0"
    else:
        decimals = max(0, 2 - math.floor(math.log10(abs(value))))
        text = f"{value:,.{decimals}f}"
    return f"{text} {unit}".rstrip()


def _suite_figures(suite: str, results_dir: Path) -> tuple[Path, Mapping[str, Any], str]:
    """The results file of ``suite`` (full, else quick), its figures and the command that made it."""
    full, quick = results_path(results_dir, suite, False), results_path(results_dir, suite, True)
    path = full if full.is_file() else quick
    if not path.is_file():
        raise BenchError(
            f"bench-table {suite}: no results file {full} (nor {quick}); run `negobs bench {suite}`"
        )
    command = f"`negobs bench {suite}{' --quick' if path == quick else ''}`"
    return path, read_results(path)["figures"], command


def _table(suite: str, keys: list[str], results_dir: Path) -> str:
    """The rows of one block: each key of ``suite``, or ``OTHER.key`` of suite ``OTHER``."""
    loaded: dict[str, tuple[Path, Mapping[str, Any], str]] = {}

    def figures_of(name: str) -> tuple[Path, Mapping[str, Any], str]:
        if name not in loaded:
            loaded[name] = _suite_figures(name, results_dir)
        return loaded[name]

    rows = []
    for qualified in keys or list(figures_of(suite)[1]):
        owner, _, key = qualified.rpartition(".")
        path, figures, command = figures_of(owner or suite)
        if key not in figures:
            raise BenchError(f"bench-table {owner or suite}: figure {key!r} is not in {path}")
        figure = figures[key]
        rows.append(f"| {figure['what']} | {format_value(figure['value'], figure['unit'])} | {command} |")
    return "\n".join([HEADER, *rows])


def fill_tables(text: str, results_dir: str | Path) -> str:
    """``text`` with every bench-table block's rows generated from the results in ``results_dir``.

    Raises:
        BenchError: a block names a suite without a results file or a key its file lacks, or a
            block is not closed.
    """
    results_dir = Path(results_dir)
    out, at = [], 0
    for block in _BLOCK.finditer(text):
        if _OPEN.search(text, at, block.start()):
            raise BenchError(f"a bench-table block is not closed before {block.group('open')!r}")
        keys = [k.strip() for k in block.group("keys").split(",") if k.strip()]
        out += [text[at : block.start()], block.group("open"), "\n"]
        out += [_table(block.group("suite"), keys, results_dir), "\n", block.group("close")]
        at = block.end()
    if _OPEN.search(text, at):
        raise BenchError("a bench-table block is not closed (no '<!-- /bench-table -->' after it)")
    return "".join([*out, text[at:]])


def markdown_files(root: str | Path = ".") -> list[Path]:
    """README.md and docs/*.md under ``root``, those that exist."""
    root = Path(root)
    return [p for p in [root / "README.md", *sorted((root / "docs").glob("*.md"))] if p.is_file()]


def write_tables(files: Iterable[str | Path], results_dir: str | Path) -> list[Path]:
    """Fill the tables of ``files`` (:func:`fill_tables`), writing atomically those that changed;
    the changed files. Every file is checked before any is written."""
    changed = []
    for path in map(Path, files):
        text = path.read_text(encoding="utf-8")
        try:
            new = fill_tables(text, results_dir)
        except BenchError as error:
            raise BenchError(f"{path}: {error}") from error
        if new != text:
            changed.append((path, new))
    for path, new in changed:
        write_text_atomic(path, new)
    return [path for path, _ in changed]
