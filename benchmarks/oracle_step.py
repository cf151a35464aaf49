"""Control steps per second of the training envs with the oracle grid, per stage, in one process.

Run: ``python benchmarks/oracle_step.py [--steps 600] [--env-id negobs_gym/OffroadNav-v1 ...]``

The oracle grid (``source="oracle"``: the ground truth rasterised around the true pose, no
sensors) is what the shipped navigation policies were trained on (docs/training.md). Each env
drives ``--steps`` steps at constant half throttle from seed 0, resetting on episode ends with
the next seed (a new terrain each). Stages, milliseconds per step: ``physics`` = ``World.step``
(its sub-steps and the event checks), of which ``events`` = the event checks; ``grid`` = the
oracle layers; ``info`` = the step's ``info`` (the ground-truth distances ahead); ``other`` = the
rest of ``NegObsEnv.step`` (outcome, rewards, state, pooling). Resets are timed apart
(``reset_s_mean``). The last line is ``oracle_train_steps_per_s=<v>``, the first env's steps per
second (resets excluded).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from env_step import StageTimer  # this directory's benchmark

from negobs_gym.envs import base as env_base
from negobs_gym.envs.sources import OracleSource
from negobs_gym.policies.training import make_task_env
from negobs_gym.sim.events import EventMonitor
from negobs_gym.sim.world import World

ACTION = np.array([0.5, 0.0], np.float32)
STAGES = ("physics", "events", "grid", "info")


def drive(env_id: str, steps: int) -> tuple[dict[str, float], float, float, int]:
    """Per-stage milliseconds per step, steps/s and mean reset seconds over ``steps`` steps, and
    the number of resets."""
    with StageTimer() as timer:
        timer.wrap(World, "step", "physics")
        timer.wrap(EventMonitor, "_check", "events")  # before the envs: monitors hook the bound method
        timer.wrap(OracleSource, "layers", "grid")
        timer.wrap(env_base.NegObsEnv, "_info", "info")
        env = make_task_env(env_id, "oracle")
        env.reset(seed=0)
        env.step(ACTION)
        timer.clear()
        in_resets = dict.fromkeys(STAGES, 0.0)  # what the resets (builds, settling, first frame) took
        step_s = reset_s = 0.0
        resets, seed = 0, 1
        for _ in range(steps):
            t0 = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(ACTION)
            step_s += time.perf_counter() - t0
            if terminated or truncated:
                before = {stage: timer.total_s[stage] for stage in STAGES}
                t0 = time.perf_counter()
                env.reset(seed=seed)
                reset_s += time.perf_counter() - t0
                for stage in STAGES:
                    in_resets[stage] += timer.total_s[stage] - before[stage]
                resets, seed = resets + 1, seed + 1
        env.close()
    ms = {stage: 1e3 * (timer.total_s[stage] - in_resets[stage]) / steps for stage in STAGES}
    ms["other"] = 1e3 * step_s / steps - ms["physics"] - ms["grid"] - ms["info"]
    return ms, steps / step_s, reset_s / max(1, resets), resets


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=600, help="control steps per env")
    parser.add_argument(
        "--env-id",
        action="append",
        help="env to drive (repeatable; default OffroadNav-v1, -v2 and -v0)",
    )
    args = parser.parse_args()
    if args.steps < 1:
        parser.error("--steps must be >= 1")
    env_ids = args.env_id or [f"negobs_gym/OffroadNav-v{v}" for v in (1, 2, 0)]
    rates = []
    for env_id in env_ids:
        ms, sps, reset_s, resets = drive(env_id, args.steps)
        stages = " ".join(f"{k}={v:.2f}" for k, v in ms.items())
        print(f"env={env_id} obs=oracle steps={args.steps} stage_ms: {stages}")
        print(f"env={env_id} obs=oracle steps_per_s={sps:.1f} reset_s_mean={reset_s:.3f} resets={resets}")
        rates.append(sps)
    print(f"oracle_train_steps_per_s={rates[0]:.1f}")


if __name__ == "__main__":
    main()
