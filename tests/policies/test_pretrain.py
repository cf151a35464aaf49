"""Warm start: demonstrations of the pure-pursuit driver and behaviour cloning into a PPO policy."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.drivers.pure_pursuit import PurePursuitDriver
from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import TrainConfig, WarmStartConfig
from negobs_gym.policies.pretrain import DEMO_SEED_OFFSET, collect_demonstrations, warm_start
from negobs_gym.policies.training import _new_model, _vec_env, make_env

ENV = "negobs_gym/OffroadNav-v1"


@pytest.fixture(scope="module")
def demos():
    env = make_env(ENV, "oracle", use_filter=False)
    try:
        yield collect_demonstrations(env, 160, noise_std=0.3, seed=7)
    finally:
        env.close()


def test_demonstrations_label_the_drivers_clean_actions(demos) -> None:
    assert demos.actions.shape == (160, 2) and demos.episodes >= 1
    assert demos.observations["grid"].shape == (160, 2 * 36 * 16)
    assert demos.observations["state"].shape == (160, 11)
    # replay the first episode: the labels are the driver's actions on the recorded observations
    env = make_env(ENV, "oracle", use_filter=False)
    obs, info = env.reset(seed=7 + DEMO_SEED_OFFSET)
    driver = PurePursuitDriver(env.unwrapped.terrain.track.centreline_xy_m)
    np.testing.assert_array_equal(demos.observations["state"][0], obs["state"])
    np.testing.assert_array_equal(demos.actions[0], driver.act(obs, info))
    env.close()
    # the executed actions carried noise: the demonstrated speeds are not one deterministic ramp
    assert np.std(np.diff(demos.observations["state"][:40, 0])) > 0


def test_behaviour_cloning_fits_the_driver_and_sets_the_exploration(demos) -> None:
    config = TrainConfig(env=ENV, source="oracle", n_steps=64)
    venv = _vec_env(config)
    model = _new_model(config, venv, (2, 36, 16))
    venv.close()
    before, _ = model.predict(demos.observations, deterministic=True)
    ws = WarmStartConfig(steps=160, epochs=30, action_std=0.25)
    losses = warm_start(model, demos, ws, seed=0)
    after, _ = model.predict(demos.observations, deterministic=True)
    error_before = np.mean((before - demos.actions) ** 2)
    error_after = np.mean((after - demos.actions) ** 2)
    assert losses[-1] < 0.5 * losses[0]
    assert error_after < 0.25 * error_before
    np.testing.assert_allclose(model.policy.log_std.detach().numpy(), np.log(0.25), rtol=1e-6)


def test_warm_start_is_ppo_only_and_validated() -> None:
    with pytest.raises(ConfigError, match="warm_start"):
        TrainConfig(algo="SAC", warm_start=WarmStartConfig(steps=100))
    with pytest.raises(ConfigError, match="action_std"):
        WarmStartConfig(action_std=0.0)
    with pytest.raises(ConfigError, match="steps"):
        WarmStartConfig(steps=-1)
