"""Braking safety at 25 km/h: the reckless driver with and without the safety filter, two geometries.

Runs the braking campaign (:mod:`negobs_gym.eval.braking_campaign`, the same episodes as ``negobs
eval braking``) for the reckless driver, who holds full throttle up to 25 km/h and never brakes, on
two scenarios: ``ditch`` (Braking-v0's 1.0 m long, 3.0 m wide, 0.8 m deep ditch, near edge 20-40 m
ahead) and a narrower one, ``--narrow`` (default ``trench_narrow``: 0.4 m along the track, paper N's
0.30 m minimum width plus 10 cm, 6 m across the whole track, 1.0 m deep; a pit narrower than the
track, like ``pit_100x50``, lets the unfiltered car straddle it). The filter
(``BrakingSafetyFilter``, paper N Eq. 18: mu 0.65, T_r 0.25 s, B 5 m) sees only the detector grid of
the envs' default observation (paper N's native-resolution rig cast in the grid's ROI + LUX, sensor
noise on). An episode ends on entering the obstacle, after 1 s at standstill, or at the 15 s limit.
Episodes are kept under ``--out`` (``--resume`` continues a killed run; the parts are shared with
``negobs eval braking --out`` for the same seeds). Prints one line per configuration; the last lines
are ``narrow_stopped_before=<k>/<n>`` and, last, ``stopped_before=<k>/<n>`` of the filtered runs.

The detector tightens paper N's pairs to the close frames' near edge, as the envs do by default
(``ObservationConfig.tighten_pairs``); ``--no-tighten-pairs`` runs paper N's fusion history.
``--scan-every K`` casts a frame every K-th control step and carries it between
(``ObservationConfig.scan_every``; the filter's timeout counts from the frames' own age);
``--far-from M`` casts and detects the grid's part beyond M metres between them
(``ObservationConfig.scan_far_from_m``).

Run: python benchmarks/braking_safety.py [--episodes 100] [--workers 2] [--narrow trench_narrow]
     [--no-baseline] [--no-tighten-pairs] [--scan-every K] [--far-from M]
"""

from __future__ import annotations

import argparse
import time

from negobs_gym.eval.braking_campaign import (
    SCENARIOS,
    BrakingCampaignConfig,
    configuration_name,
    run_braking_campaign,
    summary_line,
)
from negobs_gym.eval.campaign import Backend, RunOptions


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100, help="seeds 0..N-1 per configuration")
    parser.add_argument("--workers", type=int, default=2, help="local worker processes")
    parser.add_argument(
        "--narrow", choices=sorted(s for s in SCENARIOS if s != "free_track"), default="trench_narrow"
    )
    parser.add_argument("--out", default="outputs/braking_safety", help="campaign directory")
    parser.add_argument("--resume", action="store_true", help="keep the finished episodes under --out")
    parser.add_argument("--no-baseline", action="store_true", help="skip the unfiltered runs")
    parser.add_argument(
        "--tighten-pairs",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="ObservationConfig.tighten_pairs (docs/detector_features.md, 'Near edge')",
    )
    parser.add_argument(
        "--scan-every",
        type=int,
        default=1,
        help="ObservationConfig.scan_every: a LiDAR frame every K control steps (docs/performance.md)",
    )
    parser.add_argument(
        "--far-from",
        type=float,
        default=None,
        metavar="M",
        help="ObservationConfig.scan_far_from_m: with --scan-every K > 1, cast and detect the grid "
        "beyond M metres between frames",
    )
    args = parser.parse_args()
    config = BrakingCampaignConfig(
        seeds=args.episodes,
        scenarios=("ditch", args.narrow),
        drivers=("reckless",),
        filters=(True,) if args.no_baseline else (False, True),
        tighten_pairs=args.tighten_pairs,
        scan_every=args.scan_every,
        scan_far_from_m=args.far_from,
    )
    options = RunOptions(backend=Backend(workers=args.workers), resume=args.resume, progress=False)
    t0 = time.perf_counter()
    out = run_braking_campaign(config, args.out, options)
    print(f"wall time {time.perf_counter() - t0:.0f} s ({args.workers} workers)")
    by_name = {s.name: s for s in out.summaries}
    for s in out.summaries:
        print(summary_line(s))
    narrow = by_name[configuration_name(args.narrow, "reckless", True)]
    ditch = by_name[configuration_name("ditch", "reckless", True)]
    print(f"narrow={args.narrow} narrow_stopped_before={narrow.stopped_before}/{narrow.episodes}")
    print(f"stopped_before={ditch.stopped_before}/{ditch.episodes}")


if __name__ == "__main__":
    main()
