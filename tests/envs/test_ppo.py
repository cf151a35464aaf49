"""PPO on the grid observation behind the braking safety filter: trains, saves and loads.

A tiny variant runs by default; the few-thousand-step one is ``slow``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.safety import BrakingSafetyFilter


class VetoCounter(gym.Wrapper):
    """Counts the filter's vetoes seen from outside, as a training loop would."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.steps = 0
        self.vetoes = 0

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.steps += 1
        self.vetoes += bool(info["safety"]["vetoed"])
        assert info["cost"] in (0.0, 1.0)
        return obs, reward, terminated, truncated, info


def _train_save_load(tmp_path, total_steps: int, n_steps: int = 64) -> tuple[int, VetoCounter]:
    """Train with the filter on (a rollout of ``n_steps`` per update), save, load; check both
    predict the same; return steps and counter."""
    from stable_baselines3 import PPO

    env = VetoCounter(BrakingSafetyFilter(gym.make("negobs_gym/Braking-v0")))
    model = PPO(
        "MultiInputPolicy", env, n_steps=n_steps, batch_size=n_steps // 2, n_epochs=1, seed=0, device="cpu"
    )
    model.learn(total_timesteps=total_steps)
    path = tmp_path / "ppo_braking_filter.zip"
    model.save(path)
    loaded = PPO.load(path, device="cpu")
    obs, _ = env.reset(seed=0)
    a1, _ = model.predict(obs, deterministic=True)
    a2, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(a1, a2)
    assert env.action_space.contains(a2.astype(np.float32))
    env.close()
    return loaded.num_timesteps, env


def test_ppo_tiny_train_save_load_with_filter(tmp_path) -> None:
    steps, counter = _train_save_load(tmp_path, 32, n_steps=32)  # one update of two minibatches
    assert steps >= 32 and counter.steps >= 32


@pytest.mark.slow
def test_ppo_few_thousand_steps_with_filter(tmp_path) -> None:
    steps, counter = _train_save_load(tmp_path, 2048)
    assert steps >= 2048
    # 2048 steps of a random-ish policy at 25 km/h towards a ditch 20-40 m ahead: the filter acts
    assert counter.vetoes > 0
