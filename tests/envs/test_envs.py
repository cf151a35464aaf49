"""Tests of the registered negobs envs: API checks, action validation, determinism, rendering."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.errors import ActionError, ConfigError
from negobs_gym.registration import ENV_SPECS, SCENES
from negobs_gym.spec import EpisodeSpec, ObservationConfig, RewardConfig
from negobs_gym.spec.library import load_scenario

IDS = [spec[0] for spec in ENV_SPECS]


def _one_short_world(env_id: str) -> dict:
    """One world build, not 12; a winding course at its shortest (60 m), which builds ~4x faster:
    the checkers test the API, which does not depend on the course's length."""
    overrides = {"episode.terrain_pool_size": 1}
    if load_scenario(SCENES[env_id]).terrain.preset == "winding_course":
        overrides["terrain.params.length_m"] = 60.0
    return overrides


# SB3's checker takes the uint8 grid for a camera image for its default CnnPolicy; the package's
# extractor reads 0/1 (or count) cells at any size (docs/training.md, "The extractor")
@pytest.mark.filterwarnings("ignore:It seems that your observation space grid is an image")
@pytest.mark.filterwarnings("ignore:The minimal resolution for an image")
@pytest.mark.parametrize("env_id", IDS)
def test_env_checkers_pass_on_every_registered_id(env_id: str) -> None:
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = gym.make(env_id, overrides=_one_short_world(env_id))
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
        EpisodeSpec(control_hz=float("nan"))
    with pytest.raises(ConfigError, match="time"):
        RewardConfig(time=float("inf"))
    with pytest.raises(ConfigError, match="rig"):
        ObservationConfig(rig="hdl16")
    with pytest.raises(ConfigError, match="raycast_backend"):
        ObservationConfig(raycast_backend="optix")


def test_detector_grid_sees_the_braking_ditch_and_feeds_the_hazards() -> None:
    from negobs_gym.envs.scenarios import BrakingEnv

    env = BrakingEnv()
    assert env.scenario.observation.source == "detector"
    _, info = env.reset(seed=3)
    bumper_m = env.unwrapped._vehicle.config.length_m - env.unwrapped._vehicle.config.rear_overhang_m
    # hold 25 km/h until the bumper is 6.5 m from the ditch: the rear axle is then 10.2 m away, inside
    # R(25 km/h) = 10.52 m (paper N Eq. 18), so the ditch must be in the grid by now
    while info["distance_to_negative_ahead_m"] > 6.5:
        obs, _, terminated, _, info = env.step(np.array([0.3, 0.0], np.float32))
        assert not terminated
    k = env.scenario.observation.channels.index("negative")
    assert obs["grid"][k].any(), "the detector grid shows no ditch 6.5 m ahead"
    state = env.hazard_state()
    assert state.front_length_m == pytest.approx(bumper_m)  # the corridor reaches the front corners
    hazards = state.negative_obstacles_xy_m
    straight_ahead = hazards[np.abs(hazards[:, 0]) < 1.0]
    truth_m = info["distance_to_negative_ahead_m"] + bumper_m  # from the rear axle
    # the outline runs from the last ground point A before the rim, up to a ring gap short of it:
    # the detected near edge may be early (conservative) but never beyond the rim
    assert truth_m - 1.5 < straight_ahead[:, 1].min() < truth_m + 0.3
    env.close()


def test_oracle_observation_still_takes_hazards_from_the_detector() -> None:
    from negobs_gym.envs.scenarios import BrakingEnv

    env = BrakingEnv(
        overrides={"observation.source": "oracle", "start.speed_mps": 7.0, "episode.time_limit_s": 30.0}
    )
    for seed in range(20):  # a ditch inside the oracle grid but beyond the detector's 20 m range
        obs, info = env.reset(seed=seed)
        if info["distance_to_negative_ahead_m"] < 20.0:
            break
    k = env.scenario.observation.channels.index("negative")
    assert obs["grid"][k].any()  # ground truth sees it
    assert len(env.hazard_state().negative_obstacles_xy_m) == 0  # the detector does not yet
    env.close()


@pytest.mark.parametrize("rig", ["reduced", "native"])
def test_rigs_and_backends_give_the_same_observation_layout(rig: str) -> None:
    from negobs_gym.envs.scenarios import BrakingEnv

    backend = "pybullet" if rig == "reduced" else "auto"
    env = BrakingEnv(
        overrides={"observation.rig": rig, "observation.raycast_backend": backend, "start.speed_mps": 0.0}
    )
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    obs, *_ = env.step(np.array([0.0, 0.0], np.float32))
    observed = obs["grid"][env.scenario.observation.channels.index("observed")]
    assert observed.mean() > 0.3  # the rig sees a good part of the grid around the vehicle
    env.close()
