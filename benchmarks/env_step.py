"""Control steps per second of a negobs env with the detector grid, per stage, per rig, per process count.

Run: ``python benchmarks/env_step.py [--steps 200] [--envs 2] [--env-id negobs_gym/OffroadNav-v0]``

Configurations (the env's registered config with ``ObservationConfig`` changed):

- ``rig=roi``: the default training observation (paper N's native rig cast only where the grid
  and the detectors' neighbourhoods need it, + LUX; both detectors every step);
- ``rig=native``: the full 360 deg native rig + LUX;
- ``rig=reduced``: the old half-resolution rig;
- ``obs=oracle``: the ground-truth grid (no sensors), for comparison.

Per-stage milliseconds per control step (one process, the default rig) are measured by wrapping
the stages' functions with timers: physics (``World.step``, of which the event checks), scan
synthesis, paper N's detector, paper T's detector, the rest of the step (observation stacking,
info, Python glue) and the reset. The default rig also runs vectorized with SB3 ``SubprocVecEnv``
(``--envs`` processes; steps/s counts the steps of all of them). A constant half-throttle action
drives; finished episodes are reset (their cost included). The last line is
``train_steps_per_s=<v>``: the default observation in one process.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections import defaultdict
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import negobs_gym
from negobs_gym.detector import NegativeObstacleDetector, TraversableRegionDetector
from negobs_gym.envs import base as env_base
from negobs_gym.envs import perception
from negobs_gym.sim.events import EventMonitor
from negobs_gym.sim.world import World

ACTION = np.array([0.5, 0.0], np.float32)


def _make(env_id: str, source: str, rig: str):
    def thunk():
        # "module:id" makes gymnasium import negobs_gym (and so register) inside a subprocess
        spec_id = f"negobs_gym:{env_id}"
        probe = gym.make(spec_id)
        cfg = probe.unwrapped.default_config()
        probe.close()
        obs = dataclasses.replace(cfg.observation, source=source, rig=rig)
        return gym.make(spec_id, config=dataclasses.replace(cfg, observation=obs))

    return thunk


def _drive(env: gym.Env, steps: int, seed: int = 0) -> tuple[float, int]:
    """Steps/s over ``steps`` control steps (resets included) and the number of resets."""
    env.reset(seed=seed)
    resets = 0
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, term, trunc, _ = env.step(ACTION)
        if term or trunc:
            env.reset(seed=seed + k + 1)
            resets += 1
    return steps / (time.perf_counter() - t0), resets


class StageTimer:
    """Wraps functions with accumulating wall-clock timers (restored on exit)."""

    def __init__(self) -> None:
        self.total_s: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._undo: list[Callable[[], None]] = []

    def wrap(self, owner: object, attr: str, stage: str) -> None:
        original = getattr(owner, attr)

        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.total_s[stage] += time.perf_counter() - t0
                self.calls[stage] += 1

        setattr(owner, attr, timed)
        self._undo.append(lambda: setattr(owner, attr, original))

    def __enter__(self) -> StageTimer:
        return self

    def __exit__(self, *exc: object) -> None:
        for undo in reversed(self._undo):
            undo()


def stage_breakdown(env_id: str, rig: str, steps: int) -> tuple[dict[str, float], float, int]:
    """Milliseconds per control step by stage (reset: per reset), steps/s and the reset count."""
    env = _make(env_id, "detector", rig)()
    env.reset(seed=0)  # first make/reset (imports, first masks) outside the timing
    with StageTimer() as timer:
        timer.wrap(World, "step", "physics")
        timer.wrap(EventMonitor, "_check", "events")
        timer.wrap(perception, "scan_rig", "scan")
        timer.wrap(NegativeObstacleDetector, "update", "paper_n")
        timer.wrap(TraversableRegionDetector, "update", "paper_t")
        timer.wrap(env_base.NegObsEnv, "step", "step")
        timer.wrap(env_base.NegObsEnv, "reset", "reset")
        sps, resets = _drive(env, steps, seed=1)
    env.close()
    t = timer.total_s
    ms = {
        "physics": 1e3 * t["physics"] / steps,
        "events": 1e3 * t["events"] / steps,
        "scan": 1e3 * t["scan"] / steps,
        "paper_n": 1e3 * t["paper_n"] / steps,
        "paper_t": 1e3 * t["paper_t"] / steps,
    }
    inner = t["physics"] + t["scan"] + t["paper_n"] + t["paper_t"]
    ms["other"] = 1e3 * (t["step"] - inner) / steps
    ms["reset_per_reset"] = 1e3 * t["reset"] / max(1, timer.calls["reset"])
    ms["reset_per_step"] = 1e3 * t["reset"] / steps
    return ms, sps, resets


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="negobs_gym/OffroadNav-v0")
    parser.add_argument("--steps", type=int, default=200, help="control steps per configuration")
    parser.add_argument("--envs", type=int, default=2, help="processes of the vectorized run")
    parser.add_argument("--skip-others", action="store_true", help="only the default rig")
    args = parser.parse_args()
    if args.steps < 1 or args.envs < 1:
        parser.error("--steps and --envs must be >= 1")
    default_rig = negobs_gym.envs.config.ObservationConfig().rig
    t0 = time.perf_counter()
    env = _make(args.env_id, "detector", default_rig)()
    env.reset(seed=0)
    print(f"env={args.env_id} first_make_and_reset_s={time.perf_counter() - t0:.2f}")
    env.close()
    if not args.skip_others:
        for source, rig in (("detector", "native"), ("detector", "reduced"), ("oracle", default_rig)):
            label = f"obs={source}" + (f" rig={rig}" if source == "detector" else "")
            sps, _ = _drive(_make(args.env_id, source, rig)(), max(20, args.steps // 4))
            print(f"{label} processes=1 steps_per_s={sps:.1f}")
    ms, sps, resets = stage_breakdown(args.env_id, default_rig, args.steps)
    stages = " ".join(f"{k}={v:.2f}" for k, v in ms.items())
    print(f"stage_ms rig={default_rig} steps={args.steps} resets={resets}: {stages}")
    vec = _run_vec(args.env_id, "detector", default_rig, max(1, args.steps // args.envs), args.envs)
    print(f"obs=detector rig={default_rig} processes={args.envs} steps_per_s={vec:.1f} ratio={vec / sps:.2f}")
    print(f"train_steps_per_s={sps:.1f}")


if __name__ == "__main__":
    main()
