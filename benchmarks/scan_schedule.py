"""Benchmark: steps/s of the detector grid's frame schedules, alternating in one process.

The schedules (``ObservationConfig``): a LiDAR frame every step (the default), ``scan_every=k``
with the last frame carried between, and ``scan_every=k`` with the grid's part beyond
``scan_far_from_m`` cast and detected between (docs/performance.md, "Casting the far part between
frames"). The machine's speed drifts by 20-40 % within minutes, so the schedules run in turns:
``--rounds`` rounds, each driving every schedule's env ``--steps`` steps at half throttle
(resetting finished episodes, seeds from 0 per env, so every schedule drives the same episodes).
Prints per schedule the wall and CPU (``time.process_time``) per step summed over the rounds and
their ratios to every step; the last line is ``far_cpu_ratio=`` (CPU per step of the first far
schedule over every step's).

Run: python benchmarks/scan_schedule.py [--env-id negobs_gym/OffroadNav-v0] [--steps 60]
     [--rounds 3] [--every 3,4] [--far-from 8,12]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401  (registers the envs)

ACTION = np.array([0.5, 0.0], np.float32)


def make_env(env_id: str, **observation) -> gym.Env:
    """``env_id``'s registered config with the observation fields changed."""
    probe = gym.make(env_id)
    cfg = probe.unwrapped.default_config()
    probe.close()
    obs = dataclasses.replace(cfg.observation, **observation)
    return gym.make(env_id, config=dataclasses.replace(cfg, observation=obs))


class Driven:
    """One schedule's env, driven block by block over the same episode stream as the others."""

    def __init__(self, env: gym.Env) -> None:
        self.env, self.episodes, self.wall_s, self.cpu_s, self.steps = env, 0, 0.0, 0.0, 0
        env.reset(seed=0)

    def drive(self, steps: int) -> None:
        for _ in range(steps):
            w, c = time.perf_counter(), time.process_time()
            _, _, terminated, truncated, _ = self.env.step(ACTION)
            self.wall_s += time.perf_counter() - w
            self.cpu_s += time.process_time() - c
            self.steps += 1
            if terminated or truncated:
                self.episodes += 1
                self.env.reset(seed=self.episodes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="negobs_gym/OffroadNav-v0")
    parser.add_argument("--steps", type=int, default=60, help="steps per schedule per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--every", default="3,4", help="comma-separated scan_every values (> 1)")
    parser.add_argument("--far-from", default="8,12", help="comma-separated scan_far_from_m values [m]")
    args = parser.parse_args()
    every = [int(k) for k in args.every.split(",") if k.strip()]
    far = [float(m) for m in args.far_from.split(",") if m.strip()]
    if args.steps < 1 or args.rounds < 1 or any(k < 2 for k in every):
        parser.error("--steps and --rounds must be >= 1, --every values >= 2")
    schedules = {"every step": {}}
    for k in every:
        schedules[f"scan_every={k}"] = {"scan_every": k}
        for m in far:
            schedules[f"scan_every={k} scan_far_from_m={m:g}"] = {"scan_every": k, "scan_far_from_m": m}
    driven = {name: Driven(make_env(args.env_id, **obs)) for name, obs in schedules.items()}
    for _ in range(args.rounds):
        for d in driven.values():
            d.drive(args.steps)
    base = driven["every step"]
    print(f"env={args.env_id} rounds={args.rounds} steps_per_round={args.steps} (one process)")
    for name, d in driven.items():
        wall_ms, cpu_ms = 1e3 * d.wall_s / d.steps, 1e3 * d.cpu_s / d.steps
        print(
            f"{name:<34} steps_per_s={1e3 / wall_ms:5.1f} cpu_ms={cpu_ms:5.1f} "
            f"speed_ratio={base.wall_s / d.wall_s:.2f} cpu_ratio={d.cpu_s / base.cpu_s:.2f}"
        )
        d.env.close()
    first_far = next((d for name, d in driven.items() if "far" in name), None)
    if first_far is not None:
        print(f"far_cpu_ratio={first_far.cpu_s / base.cpu_s:.2f}")


if __name__ == "__main__":
    main()
