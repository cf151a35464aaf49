"""Warm start: demonstrations of a scripted driver and behaviour cloning into a PPO policy."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.drivers.pure_pursuit import PurePursuitDriver
from negobs_gym.drivers.track_planner import TrackPlannerConfig, TrackPlannerDriver
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
    with pytest.raises(ConfigError, match="driver"):
        WarmStartConfig(driver="reckless")
    with pytest.raises(ConfigError, match="planner_sight_m"):
        WarmStartConfig(planner_sight_m=float("nan"))


def test_track_planner_demonstrations_pass_the_first_obstacle_on_offroad_nav_v2() -> None:
    env = make_env("negobs_gym/OffroadNav-v2", "oracle", use_filter=False)
    try:
        demos = collect_demonstrations(env, 120, noise_std=0.0, seed=0, driver="track_planner")
        obs, info = env.reset(seed=DEMO_SEED_OFFSET)
        first = TrackPlannerDriver(env.unwrapped.terrain).act(obs, info)
    finally:
        env.close()
    np.testing.assert_array_equal(demos.actions[0], first)
    # the first obstacle of every winding course is at ~25 m, where the centre-line driver enters
    # it (tests/drivers/test_track_planner.py): 120 steps of the planner drive past it in one episode
    assert demos.episodes == 1
    assert np.abs(demos.actions[:, 1]).max() > 0.1  # it steered around


def test_dagger_rollouts_execute_the_policy_and_label_with_the_driver() -> None:
    full_throttle = np.array([1.0, 0.0], dtype=np.float32)
    env = make_env(ENV, "oracle", use_filter=False)
    try:
        demos = collect_demonstrations(env, 30, 0.0, 3, policy=lambda obs: full_throttle, first_episode=5)
        # replay: the same course (episode 5), the policy's action executed, the driver's as labels
        obs, info = env.reset(seed=3 + DEMO_SEED_OFFSET + 5)
        driver = PurePursuitDriver(env.unwrapped.terrain.track.centreline_xy_m)
        labels = []
        for _ in range(30):
            labels.append(driver.act(obs, info))
            obs, _, _, _, info = env.step(full_throttle)
    finally:
        env.close()
    np.testing.assert_array_equal(demos.actions, np.stack(labels))
    assert not np.allclose(demos.actions[:, 0], 1.0)  # the driver would have eased off at cruise speed
    both = demos + demos
    assert both.actions.shape == (60, 2) and both.episodes == 2
    np.testing.assert_array_equal(both.observations["grid"][30:], demos.observations["grid"])


def test_a_sight_limited_planner_labels_what_it_sees() -> None:
    env = make_env("negobs_gym/OffroadNav-v2", "oracle", use_filter=False)
    try:
        full = collect_demonstrations(env, 80, noise_std=0.0, seed=0, driver="track_planner")
        near = collect_demonstrations(env, 80, 0.0, 0, "track_planner", planner_sight_m=14.0)
        obs, info = env.reset(seed=DEMO_SEED_OFFSET)
        driver = TrackPlannerDriver(env.unwrapped.terrain, TrackPlannerConfig(sight_m=14.0))
        labels = []
        for _ in range(80):
            labels.append(driver.act(obs, info))
            obs, _, _, _, info = env.step(labels[-1])
    finally:
        env.close()
    np.testing.assert_array_equal(near.actions, np.stack(labels))
    assert driver.replans >= 1  # the first obstacle came into sight on the way
    assert not np.array_equal(near.actions, full.actions)  # the whole course's path starts earlier
