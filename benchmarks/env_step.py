"""Control steps per second of a negobs env: detector observation on both rigs, and the oracle.

Run: ``python benchmarks/env_step.py [--steps 60] [--envs 2] [--env-id negobs_gym/Braking-v0]``

Configurations (the env's registered config with ``ObservationConfig`` changed):

- ``obs=detector rig=reduced``: the training rig (paper N's rig at half resolution + LUX, Embree
  casts, both detectors every step) - the default observation;
- ``obs=detector rig=native``: paper N's full-resolution rig + LUX;
- ``obs=oracle``: the ground-truth grid (no sensors), for comparison.

Each runs in one process and vectorized with SB3 ``SubprocVecEnv`` (``--envs`` processes; steps/s
counts the steps of all of them). A constant half-throttle action drives; finished episodes are
reset. Also prints the first reset time and the ``rgb_array`` render time per frame.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401 - registers the envs

ACTION = np.array([0.5, 0.0], np.float32)


def _make(env_id: str, source: str, rig: str, render_mode: str | None = None):
    def thunk():
        # "module:id" makes gymnasium import negobs_gym (and so register) inside a subprocess
        spec_id = f"negobs_gym:{env_id}"
        probe = gym.make(spec_id)
        cfg = probe.unwrapped.default_config()
        probe.close()
        obs = dataclasses.replace(cfg.observation, source=source, rig=rig)
        return gym.make(spec_id, config=dataclasses.replace(cfg, observation=obs), render_mode=render_mode)

    return thunk


def _run_single(env_id: str, source: str, rig: str, steps: int) -> float:
    env = _make(env_id, source, rig)()
    env.reset(seed=0)
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, term, trunc, _ = env.step(ACTION)
        if term or trunc:
            env.reset(seed=k + 1)
    dt = time.perf_counter() - t0
    env.close()
    return steps / dt


def _run_vec(env_id: str, source: str, rig: str, steps: int, n_envs: int) -> float:
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = SubprocVecEnv([_make(env_id, source, rig) for _ in range(n_envs)])
    venv.seed(0)
    venv.reset()
    actions = np.tile(ACTION[None], (n_envs, 1))
    venv.step(actions)  # first step outside the timing (workers warm)
    t0 = time.perf_counter()
    for _ in range(steps):
        venv.step(actions)  # SB3 auto-resets finished envs
    dt = time.perf_counter() - t0
    venv.close()
    return steps * n_envs / dt


def _render_ms(env_id: str, frames: int) -> float:
    env = _make(env_id, "detector", "reduced", render_mode="rgb_array")()
    env.reset(seed=0)
    env.render()  # the terrain overview is drawn once per terrain and cached
    total = 0.0
    for _ in range(frames):
        env.step(ACTION)
        t0 = time.perf_counter()
        env.render()
        total += time.perf_counter() - t0
    env.close()
    return 1000.0 * total / frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="negobs_gym/Braking-v0")
    parser.add_argument("--steps", type=int, default=60, help="control steps per configuration")
    parser.add_argument("--envs", type=int, default=2, help="processes of the vectorized runs")
    args = parser.parse_args()
    if args.steps < 1 or args.envs < 1:
        parser.error("--steps and --envs must be >= 1")
    t0 = time.perf_counter()
    env = _make(args.env_id, "detector", "reduced")()
    env.reset(seed=0)
    print(f"env={args.env_id} first_make_and_reset_s={time.perf_counter() - t0:.2f}")
    env.close()
    print(f"render_ms_per_frame={_render_ms(args.env_id, 20):.2f} (rgb_array, reduced rig)")
    for source, rig in (("detector", "reduced"), ("detector", "native"), ("oracle", "reduced")):
        label = f"obs={source}" + (f" rig={rig}" if source == "detector" else "")
        sps = _run_single(args.env_id, source, rig, args.steps)
        print(f"{label} processes=1 steps_per_s={sps:.1f}")
        sps = _run_vec(args.env_id, source, rig, max(1, args.steps // args.envs), args.envs)
        print(f"{label} processes={args.envs} steps_per_s={sps:.1f}")


if __name__ == "__main__":
    main()
