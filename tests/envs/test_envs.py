"""Tests of the registered negobs envs: API checks, action validation, determinism, rendering."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.envs.config import EnvConfig, ObservationConfig, RewardConfig
from negobs_gym.errors import ActionError, ConfigError
from negobs_gym.registration import ENV_SPECS

IDS = [spec[0] for spec in ENV_SPECS]


@pytest.mark.parametrize("env_id", IDS)
def test_env_checkers_pass_on_every_registered_id(env_id: str) -> None:
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = gym.make(env_id)
    gym_check(env.unwrapped, skip_render_check=True)
    sb3_check(env.unwrapped, warn=True)
    env.close()


def test_registry_lists_the_issue_ids() -> None:
    assert {"negobs_gym/OffroadNav-v0", "negobs_gym/Braking-v0", "negobs_gym/TrenchCrossing-v0"} <= set(IDS)
    for env_id in IDS:
        assert env_id in gym.registry


def test_braking_step_contract_and_nan_action() -> None:
    env = gym.make("negobs_gym/Braking-v0", render_mode="rgb_array")
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert info["speed_mps"] > 6.0  # starts at 25 km/h
    assert 10.0 < info["distance_to_negative_ahead_m"] < 45.0
    with pytest.raises(ActionError):
        env.step(np.array([np.nan, 0.0], np.float32))
    obs, reward, _terminated, _truncated, info = env.step(np.array([-1.0, 0.0], np.float32))
    assert env.observation_space.contains(obs)
    assert reward == pytest.approx(sum(info["rewards"].values()))
    assert set(info["rewards"]) >= {"progress", "negative_entry", "collision", "time"}
    assert info["rewards"]["progress"] > 0  # still rolling forward while braking
    frame = env.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8 and frame.shape[2] == 3
    env.close()


def test_same_seed_same_rollout_bit_for_bit() -> None:
    def rollout() -> list[np.ndarray]:
        env = gym.make("negobs_gym/Braking-v0")
        obs, _ = env.reset(seed=11)
        out = [obs["state"].copy(), obs["grid"].copy()]
        for _ in range(3):
            obs, *_ = env.step(np.array([0.5, 0.2], np.float32))
            out += [obs["state"].copy(), obs["grid"].copy()]
        env.close()
        return out

    for a, b in zip(rollout(), rollout(), strict=True):
        np.testing.assert_array_equal(a, b)


def test_oracle_grid_sees_the_ditch_ahead() -> None:
    env = gym.make("negobs_gym/Braking-v0")
    obs, info = env.reset(seed=0)
    neg = obs["grid"][0]
    assert neg.any() == (info["distance_to_negative_ahead_m"] < 25.0)
    env.close()


def test_configs_reject_bad_values() -> None:
    with pytest.raises(ConfigError, match="channels"):
        ObservationConfig(channels=("negative", "bogus"))
    with pytest.raises(ConfigError, match="downsample"):
        ObservationConfig(downsample=7)
    with pytest.raises(ConfigError, match="control_hz"):
        EnvConfig(control_hz=float("nan"))
    with pytest.raises(ConfigError, match="time"):
        RewardConfig(time=float("inf"))


def test_detector_source_is_refused_with_a_clear_error() -> None:
    from negobs_gym.envs.scenarios import BrakingEnv

    with pytest.raises(ConfigError, match=r"observation\.source"):
        BrakingEnv(EnvConfig(observation=ObservationConfig(source="detector")))
