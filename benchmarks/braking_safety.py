"""Braking safety at 25 km/h: the reckless driver on Braking-v0, with and without the safety filter.

Each seeded episode starts at 25 km/h with a 1.0 m long, 3.0 m wide, 0.8 m deep ditch 20-40 m
ahead. The reckless driver holds full throttle up to 25 km/h and never brakes. The filter
(``BrakingSafetyFilter``, paper N Eq. 18: mu 0.65, T_r 0.25 s, B 5 m) sees only the detector grid
(reduced paper N rig + LUX, sensor noise on). An episode ends on entering the ditch, after 2 s at
standstill, or at the 15 s limit. Prints per-mode counts, stop margins and false vetoes; the last
line is ``stopped_before=<k>/<n>`` of the filtered runs.

Run: python benchmarks/braking_safety.py [--episodes 100] [--workers 2]
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.drivers import RecklessDriver
from negobs_gym.safety import BrakingSafetyFilter

STANDSTILL_MPS = 0.1
STANDSTILL_S = 2.0


def run_episode(seed: int, filtered: bool) -> dict[str, float]:
    """One episode; returns whether the ditch was entered, the gap left and the veto counts."""
    env = gym.make("negobs_gym/Braking-v0")
    if filtered:
        env = BrakingSafetyFilter(env)
    driver = RecklessDriver()
    driver.reset(seed)
    obs, info = env.reset(seed=seed)
    start_gap = info["distance_to_negative_ahead_m"]
    dt = 1.0 / env.unwrapped.config.control_hz
    still_s, vetoes, false_vetoes, steps = 0.0, 0, 0, 0
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
        steps += 1
        safety = info.get("safety")
        if safety is not None and safety["vetoed"]:
            vetoes += 1
            # a veto with no real ditch within the distance the filter believed is a false veto
            false_vetoes += info["distance_to_negative_ahead_m"] > safety["hazard_distance_m"] + 2.0
        still_s = still_s + dt if info["speed_mps"] < STANDSTILL_MPS else 0.0
        done = terminated or truncated or still_s >= STANDSTILL_S
    env.close()
    entered = bool(info["events"]["entered_negative_obstacle"])
    return {
        "seed": seed,
        "start_gap_m": start_gap,
        "entered": entered,
        "stopped_before": (not entered) and info["speed_mps"] < STANDSTILL_MPS,
        "gap_m": info["distance_to_negative_ahead_m"],
        "vetoes": vetoes,
        "false_vetoes": int(false_vetoes),
        "steps": steps,
    }


def _run(args: tuple[int, bool]) -> dict[str, float]:
    return run_episode(*args)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-baseline", action="store_true", help="skip the unfiltered runs")
    args = parser.parse_args()
    modes = [True] if args.no_baseline else [False, True]
    t0 = time.perf_counter()
    results: dict[bool, list[dict[str, float]]] = {}
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for filtered in modes:
            jobs = [(seed, filtered) for seed in range(args.episodes)]
            results[filtered] = list(pool.map(_run, jobs))
    for filtered in modes:
        rs = results[filtered]
        name = "filter" if filtered else "no filter"
        entered = sum(r["entered"] for r in rs)
        stopped = [r for r in rs if r["stopped_before"]]
        gaps = [r["gap_m"] for r in stopped if math.isfinite(r["gap_m"])]
        gap_txt = f"gap left median {np.median(gaps):.2f} m, min {min(gaps):.2f} m" if gaps else "no stops"
        print(
            f"{name}: entered={entered}/{len(rs)} stopped_before={len(stopped)}/{len(rs)} {gap_txt}; "
            f"vetoes={sum(r['vetoes'] for r in rs)} false_vetoes={sum(r['false_vetoes'] for r in rs)}"
        )
        for r in rs:
            if filtered and not r["stopped_before"]:
                print(f"  seed {r['seed']}: ditch at {r['start_gap_m']:.1f} m, entered={r['entered']}")
    print(f"wall time {time.perf_counter() - t0:.0f} s")
    k = sum(r["stopped_before"] for r in results[True])
    print(f"stopped_before={k}/{len(results[True])}")


if __name__ == "__main__":
    main()
