"""``negobs demo``: the quick-start braking demo (:mod:`negobs_gym.demo`) and a small detection campaign."""

from __future__ import annotations

import argparse
import logging

from negobs_gym.cli.common import non_negative_int, positive_int

log = logging.getLogger("negobs_gym.cli.demo")

DEMO_SEEDS = 2  # two short courses of the detection campaign (see negobs_gym.eval.detection_campaign)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` command."""
    parser = subparsers.add_parser(
        "demo",
        help="braking demo (reckless driver without and with the safety filter), small detection campaign",
        description="Runs negobs_gym/Braking-v1 twice with one seed (no filter, then the Eq. 18 "
        "braking safety filter on the LiDAR detector grid) and writes both final frames to a PNG; then "
        "a small paper N detection campaign (native rig, noise on) whose tables and figures go to "
        "--eval-out.",
    )
    parser.add_argument("--out", default="outputs/demo.png", help="PNG to write (default: %(default)s)")
    parser.add_argument(
        "--seed", type=non_negative_int, default=0, help="episode seed (default: %(default)s)"
    )
    parser.add_argument(
        "--eval-out",
        default="outputs/demo_eval",
        help="directory of the detection campaign's tables and figures (default: %(default)s)",
    )
    parser.add_argument(
        "--frames", type=positive_int, default=40, help="detection campaign frames (default: %(default)s)"
    )
    parser.add_argument("--no-detection", action="store_true", help="only the braking demo")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the braking demo, then the small detection campaign; log where everything went."""
    from negobs_gym.demo import log_runs, run_demo

    log_runs(run_demo(args.out, args.seed), args.seed, args.out)
    if args.no_detection:
        return 0
    from negobs_gym.eval.detection_campaign import DetectionCampaignConfig, run_detection_campaign

    config = DetectionCampaignConfig(seeds=min(DEMO_SEEDS, args.frames), frames=args.frames)
    log.info("detection campaign: %d frames on %d seeded courses (paper N §4.2)", config.frames, config.seeds)
    out = run_detection_campaign(config, args.eval_out)
    rates = out.summary.false_alarm_rates("fused")
    log.info(
        "  %d ground-truth obstacle sightings in Table 7's bins; fused false alarms %.2f per frame",
        sum(map(sum, out.summary.occurrences)),
        rates["per_frame"],
    )
    log.info("  tables (paper N Tables 6/7 beside ours, false alarms, Fig. 16): %s", out.tables_md)
    log.info("  figures: %s, %s", out.fig16_png, out.heatmap_png)
    log.info(
        "  per-frame CSVs and JSON summary: %s, %s, %s", out.obstacles_csv, out.frames_csv, out.summary_json
    )
    return 0
