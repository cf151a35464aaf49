"""``negobs bench``: run the benchmark suites, or rewrite the docs' figure tables from their results.

``negobs bench [SUITE ...] [--quick] [--out DIR]`` runs the named suites (none: all of them,
:data:`negobs_gym.bench.SUITE_NAMES`) and writes ``DIR/SUITE.json`` each (``SUITE.quick.json``
with ``--quick``: small sizes, all four suites within minutes). ``negobs bench --tables`` runs
nothing: it regenerates every ``<!-- bench-table: ... -->`` block of README.md and docs/*.md from
those files (benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import logging

from negobs_gym.bench import (
    DEFAULT_OUT,
    SUITE_NAMES,
    BenchError,
    format_value,
    load_suite,
    markdown_files,
    run_suite,
    write_tables,
)

log = logging.getLogger("negobs_gym.cli")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``bench`` command."""
    parser = subparsers.add_parser(
        "bench",
        help="run the benchmark suites (JSON results), or regenerate the docs' figure tables",
        description="Run benchmark suites and write one JSON results file per suite, or (--tables) "
        "regenerate the figure tables of README.md and docs/*.md from those files.",
    )
    parser.add_argument(
        "suites", nargs="*", metavar="SUITE", help=f"suites to run (default: all): {', '.join(SUITE_NAMES)}"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="small sizes (all suites within minutes), written to SUITE.quick.json",
    )
    parser.add_argument(
        "--out", default=str(DEFAULT_OUT), metavar="DIR", help=f"results folder (default: {DEFAULT_OUT})"
    )
    parser.add_argument(
        "--tables",
        action="store_true",
        help="run nothing: rewrite the bench-table blocks of README.md and docs/*.md from --out",
    )
    parser.add_argument(
        "--root", default=".", metavar="DIR", help="with --tables: the folder holding README.md and docs/"
    )
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the suites, or with ``--tables`` fill the tables; 0 on success."""
    if args.tables:
        if args.suites or args.quick:
            raise BenchError("--tables runs no suite: give it without SUITE names and --quick")
        files = markdown_files(args.root)
        if not files:
            raise BenchError(f"no README.md or docs/*.md under {args.root!r}: give the repository as --root")
        changed = write_tables(files, args.out)
        log.info(
            "bench tables: %d of %d files changed%s",
            len(changed),
            len(files),
            "".join(f"\n  {p}" for p in changed),
        )
        return 0
    suites = [load_suite(name) for name in args.suites or SUITE_NAMES]  # unknown names fail before any run
    for suite in suites:
        path, results = run_suite(suite, quick=args.quick, out_dir=args.out)
        log.info(
            "bench %s: %.0f s wall, %.0f s CPU -> %s", suite.name, results["wall_s"], results["cpu_s"], path
        )
        for key, figure in results["figures"].items():
            log.info("  %s = %s  (%s)", key, format_value(figure["value"], figure["unit"]), figure["what"])
    return 0
