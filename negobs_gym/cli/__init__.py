"""The ``negobs`` command line: one console script, one module per command.

Each command lives in its own module of this package and exposes ``register(subparsers)``, which
adds its parser (``--help`` text included) and sets ``handler`` to a function ``(args) -> int``.
A new command is one new module plus one line in :data:`COMMAND_MODULES`; modules are imported
only when the command line is built, so ``negobs --help`` stays cheap.
"""

from __future__ import annotations

import argparse
import importlib
import logging
from collections.abc import Sequence

from negobs_gym import __version__
from negobs_gym.errors import NegobsError

log = logging.getLogger("negobs_gym.cli")

#: Modules of :mod:`negobs_gym.cli` that each add one top-level command, in ``--help`` order.
COMMAND_MODULES: tuple[str, ...] = (
    "demo",
    "detect",
    "bag",
    "eval",
    "scenario",
    "policy",
    "train",
    "bench",
    "pem",
)


def build_parser() -> argparse.ArgumentParser:
    """The ``negobs`` parser with every command of :data:`COMMAND_MODULES`."""
    parser = argparse.ArgumentParser(
        prog="negobs",
        description="Negative-obstacle simulation, detection, scenarios and evaluation.",
    )
    parser.add_argument("--version", action="version", version=f"negobs_gym {__version__}")
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("-v", "--verbose", action="store_true", help="debug messages")
    verbosity.add_argument("-q", "--quiet", action="store_true", help="warnings and errors only")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(f"negobs_gym.cli.{name}").register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``negobs`` console script; returns the process exit code."""
    args = build_parser().parse_args(argv)
    level = logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO
    logging.basicConfig(level=level, format="%(message)s", force=True)
    try:
        return int(args.handler(args))
    except NegobsError as error:  # the package's own, expected failures: one line, no traceback
        log.error("negobs %s: %s", args.command, error)
        return 2
    except OSError as error:
        if error.filename is None or args.verbose:  # not a file the user named: keep the traceback
            raise
        log.error("negobs %s: %s", args.command, error)  # e.g. [Errno 13] Permission denied: 'out'
        return 2
