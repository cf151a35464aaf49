"""PPO on the grid observation: trains, saves and loads (tiny fast variant; bigger one is slow)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs


def _train_save_load(tmp_path, total_steps: int) -> int:
    """Train, save, load; check both predict the same; return the loaded model's step count."""
    from stable_baselines3 import PPO

    env = gym.make("negobs_gym/Braking-v0")
    model = PPO("MultiInputPolicy", env, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=total_steps)
    path = tmp_path / "ppo_braking.zip"
    model.save(path)
    loaded = PPO.load(path, device="cpu")
    obs, _ = env.reset(seed=0)
    a1, _ = model.predict(obs, deterministic=True)
    a2, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(a1, a2)
    assert env.action_space.contains(a2.astype(np.float32))
    env.close()
    return loaded.num_timesteps


def test_ppo_tiny_train_save_load(tmp_path) -> None:
    assert _train_save_load(tmp_path, 64) >= 64


@pytest.mark.slow
def test_ppo_few_thousand_steps(tmp_path) -> None:
    assert _train_save_load(tmp_path, 2048) >= 2048
