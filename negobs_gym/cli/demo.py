"""``negobs demo``: the quick-start braking demo (see :mod:`negobs_gym.demo`)."""

from __future__ import annotations

import argparse

from negobs_gym.cli.common import non_negative_int


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` command."""
    parser = subparsers.add_parser(
        "demo",
        help="reckless driver towards a ditch without and with the safety filter; writes a PNG",
        description="Runs negobs_gym/Braking-v1 twice with one seed (no filter, then the Eq. 18 "
        "braking safety filter on the LiDAR detector grid) and writes both final frames to a PNG.",
    )
    parser.add_argument("--out", default="outputs/demo.png", help="PNG to write (default: %(default)s)")
    parser.add_argument(
        "--seed", type=non_negative_int, default=0, help="episode seed (default: %(default)s)"
    )
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the demo and log both outcomes."""
    from negobs_gym.demo import log_runs, run_demo

    log_runs(run_demo(args.out, args.seed), args.seed, args.out)
    return 0
