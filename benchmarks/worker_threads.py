"""Steps per second of 2 vector-env workers with their BLAS pinned to 1 thread (the default,
``ObservationConfig.worker_blas_threads=1``) and left at the library's own count (``None``).

Run: ``python benchmarks/worker_threads.py [--rounds 10] [--steps 50] [--env-id negobs_gym/OffroadNav-v0]``

Both vector envs (SB3's ``SubprocVecEnv``, 2 workers each, the detector grid with the default
rig) are built first, then stepped in turns (``--steps`` lockstep steps a turn, the order swapped
every round) at constant half throttle, resetting on episode ends, so a slow phase of the shared
machine hits both about equally. Each worker prints its BLAS libraries' thread counts after its
first reset. The last line is ``pinned_over_unpinned=<ratio>`` of the two rates.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from env_step import _make  # this directory's benchmark
from stable_baselines3.common.vec_env import SubprocVecEnv


def _reporting(thunk, label: str):
    """``thunk``'s env, reset once, its process's BLAS thread counts printed."""

    def make():
        from threadpoolctl import threadpool_info

        env = thunk()
        env.reset(seed=0)
        threads = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
        print(f"worker {label}: blas_threads={threads}", file=sys.stderr, flush=True)
        return env

    return make


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--steps", type=int, default=50, help="lockstep steps per turn")
    parser.add_argument("--env-id", default="negobs_gym/OffroadNav-v0")
    args = parser.parse_args()

    settings = {"pinned": 1, "unpinned": None}
    vecs = {
        label: SubprocVecEnv(
            [
                _reporting(_make(args.env_id, "detector", "roi", worker_blas_threads=threads), label)
                for _ in range(2)
            ]
        )
        for label, threads in settings.items()
    }
    action = np.tile(np.array([0.5, 0.0], np.float32), (2, 1))
    seconds = dict.fromkeys(vecs, 0.0)
    for vec in vecs.values():
        vec.seed(0)
        vec.reset()
        for _ in range(5):  # warm-up, outside the timing
            vec.step(action)
    for r in range(args.rounds):
        for label in list(vecs) if r % 2 == 0 else list(vecs)[::-1]:
            t0 = time.perf_counter()
            for _ in range(args.steps):
                vecs[label].step(action)
            seconds[label] += time.perf_counter() - t0
    steps = 2 * args.rounds * args.steps
    for label in vecs:
        print(f"workers=2 blas={label} steps_per_s={steps / seconds[label]:.2f}")
        vecs[label].close()
    print(f"pinned_over_unpinned={seconds['unpinned'] / seconds['pinned']:.4f}")


if __name__ == "__main__":
    main()
