"""Worlds built ahead of the reset: the same episodes, bit for bit, in one env and in the vector env."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.errors import ConfigError


def _oracle_braking(steps: int = 4, **episode) -> gym.Env:
    """Braking-v1 on the oracle grid, truncated after ``steps`` control steps (10 Hz)."""
    changes = {f"episode.{key}": value for key, value in episode.items()}
    changes.update({"observation.source": "oracle", "episode.time_limit_s": steps / 10.0})
    return gym.make("negobs_gym:negobs_gym/Braking-v1", overrides=changes)


def _episodes(env: gym.Env, *, ahead: bool, episodes: int = 3, steps: int = 4) -> tuple[list, int]:
    """Observations, rewards and poses of ``episodes`` seedless resets after ``reset(seed=7)``, and
    how many worlds were built ahead."""
    out, built = [], 0
    obs, _ = env.reset(seed=7)
    for _ in range(episodes):
        if ahead:
            built += env.unwrapped.build_ahead()
            assert not env.unwrapped.build_ahead()  # kept or held already: nothing to build
        out.append(obs["grid"].copy())
        for k in range(steps):
            obs, reward, _, _, info = env.step(np.array([0.6, 0.2 * (-1) ** k], np.float32))
            out += [obs["grid"].copy(), obs["state"].copy(), np.array([reward]), info["pose"]]
        obs, _ = env.reset()
    return out, built


@pytest.mark.parametrize("pool", [None, 3])
def test_a_world_built_ahead_gives_the_episode_a_fresh_build_gives(pool) -> None:
    plain, ahead = _oracle_braking(terrain_pool_size=pool), _oracle_braking(terrain_pool_size=pool)
    a, _ = _episodes(plain, ahead=False)
    b, built = _episodes(ahead, ahead=True)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    counts = ahead.unwrapped.world_cache_counts()
    # every world built ahead was drawn by the next reset (a pool's draw may repeat the kept one)
    assert built >= 2 and counts["ahead_hits"] == built
    assert plain.unwrapped.world_cache_counts()["ahead_hits"] == 0
    plain.close()
    ahead.close()


def test_a_reset_with_a_seed_closes_the_world_built_ahead() -> None:
    env = _oracle_braking()
    assert not env.unwrapped.build_ahead()  # before the first reset a seed decides
    env.reset(seed=1)
    assert env.unwrapped.build_ahead()
    held = env.unwrapped._worlds._ahead[1].world
    env.reset(seed=2)
    counts = env.unwrapped.world_cache_counts()
    assert held.closed and counts["held_ahead"] == 0 and counts["ahead_hits"] == 0
    env.close()


def _make_short_oracle() -> gym.Env:
    return _oracle_braking(steps=3)


def _lockstep(venv, pauses: bool) -> list:
    venv.seed(11)
    out = [venv.reset()]
    for k in range(10):
        if pauses and k % 3 == 0:
            time.sleep(1.0)  # the workers wait: they build their next worlds
        obs, reward, done, infos = venv.step(np.array([[0.5, 0.1], [0.3, -0.2 * (-1) ** k]], np.float32))
        out += [obs, reward, done, [info.get("terminal_observation") for info in infos]]
    return out


def _equal(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    return (a is None and b is None) or np.array_equal(a, b)


def test_build_ahead_vec_env_steps_the_episodes_subproc_vec_env_steps() -> None:
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from negobs_gym.envs.build_ahead import BuildAheadVecEnv

    plain = SubprocVecEnv([_make_short_oracle] * 2)
    try:
        expected = _lockstep(plain, pauses=False)
    finally:
        plain.close()
    venv = BuildAheadVecEnv([_make_short_oracle] * 2, idle_s=0.05)
    try:
        got = _lockstep(venv, pauses=True)
        counts = venv.env_method("world_cache_counts")
    finally:
        venv.close()
    assert _equal(expected, got)
    # 10 steps of 3-step episodes: three seedless resets per worker, most after a pause
    assert all(c["ahead_hits"] >= 2 for c in counts), counts


def test_build_ahead_vec_env_rejects_a_bad_idle_time() -> None:
    from negobs_gym.envs.build_ahead import BuildAheadVecEnv

    with pytest.raises(ConfigError, match="idle_s"):
        BuildAheadVecEnv([_make_short_oracle], idle_s=float("nan"))
