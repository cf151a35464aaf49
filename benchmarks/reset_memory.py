"""Resident memory at every reset of a long episode stream (what the slow memory test samples twice).

Drives OffroadNav-v0 (default observation: detector grid, ``roi`` rig, a new terrain every
episode) with random throttle and steering for ``--steps`` control steps, resetting on episode
ends, and prints the process's resident set size after each reset and every 250 steps. The last
lines give the min and max RSS over the resets after ``--warmup`` steps, the growth from step
``--warmup`` to the end (the slow test's figure) and the mean time of the heap release
(``envs.world_cache.release_freed_memory``). ``--no-release`` turns the release off, to measure
what it saves.

Run: ``python benchmarks/reset_memory.py [--steps 5000] [--warmup 1000] [--no-release]``
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
from sim_step import current_rss_mb as rss_mb  # this directory's benchmark

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.envs import base, world_cache


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--warmup", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-release", action="store_true", help="keep freed heap pages (no malloc_trim)")
    args = parser.parse_args()

    release_s: list[float] = []

    def timed_release() -> bool:
        if args.no_release:
            return False
        t0 = time.perf_counter()
        done = world_cache.release_freed_memory()
        release_s.append(time.perf_counter() - t0)
        return done

    base.release_freed_memory = timed_release  # the env's reference, not the module's
    env = gym.make("negobs_gym/OffroadNav-v0")
    rng = np.random.default_rng(args.seed)
    env.reset(seed=args.seed)
    at_warmup, after_warmup, episodes = None, [], 1
    for k in range(1, args.steps + 1):
        action = np.array([rng.uniform(0.2, 1.0), rng.uniform(-0.5, 0.5)], np.float32)
        _, _, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()
            episodes += 1
            rss = rss_mb()
            print(f"reset {episodes - 1} at step {k}: rss_mb={rss:.1f}", flush=True)
            if k > args.warmup:
                after_warmup.append(rss)
        if k % 250 == 0:
            print(f"step {k}: rss_mb={rss_mb():.1f}", flush=True)
        if k == args.warmup:
            at_warmup = rss_mb()
    growth = rss_mb() - at_warmup if at_warmup is not None else float("nan")
    env.close()
    release_ms = 1e3 * float(np.mean(release_s)) if release_s else float("nan")
    print(f"episodes={episodes} releases={len(release_s)} release_ms_mean={release_ms:.1f}")
    if after_warmup:
        print(f"rss_at_resets_after_warmup_mb min={min(after_warmup):.1f} max={max(after_warmup):.1f}")
    print(f"growth_after_warmup_mb={growth:.1f}")


if __name__ == "__main__":
    main()
