"""Control steps per second of the negobs envs, one process and vectorized (SubprocVecEnv).

Run: ``python benchmarks/env_step.py [--steps 100] [--envs 2] [--env-id negobs_gym/Braking-v0]``

Prints one line per configuration. Rigs: ``training`` = the registered config (4x down-sampled
grid); ``full-grid`` = the full-resolution 20 cm grid. The native sensor rig needs
``negobs_gym.sensors`` and is reported as unavailable until that package provides it.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.envs.config import EnvConfig, ObservationConfig


def _make(env_id: str, downsample: int):
    def thunk():
        # "module:id" makes gymnasium import negobs_gym (and so register) inside a subprocess
        env = gym.make(f"negobs_gym:{env_id}")
        if downsample != env.unwrapped.config.observation.downsample:
            cfg = env.unwrapped.default_config()
            cfg = dataclasses.replace(cfg, observation=ObservationConfig(downsample=downsample))
            env.close()
            env = gym.make(f"negobs_gym:{env_id}", config=cfg)
        return env

    return thunk


def _run_single(env_id: str, downsample: int, steps: int) -> float:
    env = _make(env_id, downsample)()
    env.reset(seed=0)
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, term, trunc, _ = env.step(np.array([0.3, 0.0], np.float32))
        if term or trunc:
            env.reset(seed=k)
    dt = time.perf_counter() - t0
    env.close()
    return steps / dt


def _run_vec(env_id: str, downsample: int, steps: int, n_envs: int) -> float:
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = SubprocVecEnv([_make(env_id, downsample) for _ in range(n_envs)])
    venv.seed(0)
    venv.reset()
    actions = np.tile(np.array([[0.3, 0.0]], np.float32), (n_envs, 1))
    t0 = time.perf_counter()
    for _ in range(steps):
        venv.step(actions)  # SB3 auto-resets finished envs
    dt = time.perf_counter() - t0
    venv.close()
    return steps * n_envs / dt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="negobs_gym/Braking-v0")
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--envs", type=int, default=2)
    args = parser.parse_args()
    t0 = time.perf_counter()
    env = gym.make(args.env_id)
    env.reset(seed=0)
    print(f"reset_s={time.perf_counter() - t0:.2f} (first make+reset)")
    t0 = time.perf_counter()
    env.reset(seed=1)
    print(f"reset_s={time.perf_counter() - t0:.2f} (new course)")
    env.close()
    for rig, ds in (("training", EnvConfig().observation.downsample), ("full-grid", 1)):
        print(f"rig={rig} processes=1 steps_per_s={_run_single(args.env_id, ds, args.steps):.1f}")
        sps = _run_vec(args.env_id, ds, args.steps // args.envs, args.envs)
        print(f"rig={rig} processes={args.envs} steps_per_s={sps:.1f}")
    print("rig=native unavailable (negobs_gym.sensors provides no rig yet)")


if __name__ == "__main__":
    main()
