"""Vectorized envs (gymnasium async, SB3 SubprocVecEnv) and cross-process determinism."""

from __future__ import annotations

import json
import subprocess
import sys

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401 - registers the envs

_ROLLOUT = """
import json, gymnasium as gym, numpy as np, negobs_gym
env = gym.make("negobs_gym/Braking-v0")
obs, _ = env.reset(seed=5)
out = [obs["state"].tolist(), int(obs["grid"].sum())]
for k in range(3):
    obs, r, *_ = env.step(np.array([0.4, 0.3 * (-1) ** k], np.float32))
    out += [obs["state"].tolist(), int(obs["grid"].sum()), r]
print(json.dumps(out))
"""


def _rollout_in_subprocess() -> list:
    done = subprocess.run(
        [sys.executable, "-c", _ROLLOUT], capture_output=True, text=True, check=True, timeout=120
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_one_seed_gives_identical_rollouts_in_two_processes() -> None:
    a = _rollout_in_subprocess()
    b = _rollout_in_subprocess()
    assert a == b  # exact: floats round-trip through JSON repr


def test_gymnasium_async_vector_env_runs() -> None:
    venv = gym.make_vec("negobs_gym/Braking-v0", num_envs=2, vectorization_mode="async")
    obs, _ = venv.reset(seed=[1, 2])
    assert obs["grid"].shape[0] == 2
    obs, reward, *_ = venv.step(np.zeros((2, 2), np.float32))
    assert reward.shape == (2,) and np.all(np.isfinite(reward))
    venv.close()


def _make_braking() -> gym.Env:
    # "module:id" makes gymnasium import negobs_gym (and so register) inside the subprocess
    return gym.make("negobs_gym:negobs_gym/Braking-v0")


def test_sb3_subproc_vec_env_runs() -> None:
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = SubprocVecEnv([_make_braking for _ in range(2)])
    venv.seed(3)
    obs = venv.reset()
    assert obs["state"].shape == (2, 5)
    obs, reward, _, _ = venv.step(np.zeros((2, 2), np.float32))
    assert reward.shape == (2,)
    venv.close()
