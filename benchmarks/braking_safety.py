"""Braking safety at 25 km/h: the reckless driver on Braking-v0, with and without the safety filter.

Each seeded episode starts at 25 km/h with a 1.0 m long, 3.0 m wide, 0.8 m deep ditch 20-40 m
ahead; a second geometry (``--narrow-length-m``, default 0.5 m along the track, same width and
depth) repeats the filtered runs with a ditch narrower than 1 m. The reckless driver holds full
throttle up to 25 km/h and never brakes. The filter (``BrakingSafetyFilter``, paper N Eq. 18:
mu 0.65, T_r 0.25 s, B 5 m) sees only the detector grid (the default observation: the
native-resolution paper N rig cast in the grid's ROI + LUX, sensor noise on). An episode ends on
entering the ditch, after 2 s at standstill, or at the 15 s limit. Prints per-mode counts, stop
margins and false vetoes; the last lines are ``narrow_stopped_before=<k>/<n>`` and, last,
``stopped_before=<k>/<n>`` of the filtered runs.

Run: python benchmarks/braking_safety.py [--episodes 100] [--workers 2] [--narrow-length-m 0.5]
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
from negobs_gym.envs.base import NegObsEnv
from negobs_gym.safety import BrakingSafetyFilter
from negobs_gym.scenarios import ScenarioSpec, load_scenario

STANDSTILL_MPS = 0.1
STANDSTILL_S = 2.0


def _narrow_env(ditch_length_m: float) -> gym.Env:
    """Braking-v0 with the ditch ``ditch_length_m`` long along the track (time limit included)."""
    data = load_scenario("braking_v0").to_dict()
    data["name"] = f"braking_ditch_{ditch_length_m:g}m"
    data["terrain"]["params"]["ditch_length_m"] = ditch_length_m
    return NegObsEnv(scenario=ScenarioSpec.from_dict(data))


def run_episode(seed: int, filtered: bool, ditch_length_m: float | None = None) -> dict[str, float]:
    """One episode; returns whether the ditch was entered, the gap left and the veto counts."""
    if ditch_length_m is None:
        env = gym.make("negobs_gym/Braking-v0")
    else:
        env = _narrow_env(ditch_length_m)
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


def _run(args: tuple[int, bool, float | None]) -> dict[str, float]:
    return run_episode(*args)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-baseline", action="store_true", help="skip the unfiltered runs")
    parser.add_argument(
        "--narrow-length-m", type=float, default=0.5, help="ditch length along the track, 2nd geometry [m]"
    )
    args = parser.parse_args()
    if not 0.3 <= args.narrow_length_m < 1.0:
        parser.error("--narrow-length-m must be in [0.3, 1.0) m (paper N: w_min 0.30 m)")
    modes = [True] if args.no_baseline else [False, True]
    t0 = time.perf_counter()
    results: dict[bool, list[dict[str, float]]] = {}
    narrow: list[dict[str, float]] = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        if not args.no_baseline:
            results[False] = list(pool.map(_run, [(seed, False, None) for seed in range(args.episodes)]))
        # filtered runs of both geometries interleaved, each printed when done (partial runs count)
        jobs = [
            (seed, True, length) for seed in range(args.episodes) for length in (None, args.narrow_length_m)
        ]
        results[True] = []
        for (seed, _, length), r in zip(jobs, pool.map(_run, jobs), strict=True):
            (results[True] if length is None else narrow).append(r)
            tag = "ditch" if length is None else "narrow"
            print(
                f"episode {tag} seed={seed} stopped_before={r['stopped_before']} entered={r['entered']} "
                f"gap_m={r['gap_m']:.2f}",
                flush=True,
            )
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
    for r in narrow:
        if not r["stopped_before"]:
            print(f"  narrow seed {r['seed']}: ditch at {r['start_gap_m']:.1f} m, entered={r['entered']}")
    k = sum(r["stopped_before"] for r in narrow)
    print(f"narrow_ditch_length_m={args.narrow_length_m} narrow_stopped_before={k}/{len(narrow)}")
    k = sum(r["stopped_before"] for r in results[True])
    print(f"stopped_before={k}/{len(results[True])}")


if __name__ == "__main__":
    main()
