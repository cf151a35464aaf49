"""PolicyObservation / match_observation: the flat grid SB3 does not take for an image."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from negobs_gym.envs.observation import grid_space, state_space
from negobs_gym.errors import ConfigError, InterfaceError
from negobs_gym.policies import PolicyObservation, match_observation
from negobs_gym.spec import ObservationConfig

SB3_IMAGE_WARNINGS = ("is an image", "36x36", "unconventional shape")


class StandIn(gym.Env):
    """The negobs observation and action spaces, random observations, no physics."""

    def __init__(self) -> None:
        config = ObservationConfig()
        self.observation_space = spaces.Dict({"grid": grid_space(config), "state": state_space(config)})
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return self.observation_space.sample(), {}

    def step(self, action):
        return self.observation_space.sample(), 0.0, False, False, {}


def image_warnings(record: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in record if any(k in str(w.message) for k in SB3_IMAGE_WARNINGS)]


def test_flat_grid_holds_the_same_cells_in_c_order() -> None:
    env = StandIn()
    wrapped = PolicyObservation(env)
    assert wrapped.grid_shape == (4, 36, 16)
    assert wrapped.observation_space["grid"].shape == (4 * 36 * 16,)
    assert wrapped.observation_space["grid"].dtype == np.uint8
    raw, _ = env.reset(seed=0)
    flat = wrapped.observation(raw)
    np.testing.assert_array_equal(flat["grid"], raw["grid"].ravel())
    np.testing.assert_array_equal(flat["state"], raw["state"])
    assert wrapped.observation_space.contains(flat)
    # a model trained on the flat grid gets a raw observation folded the same way
    np.testing.assert_array_equal(match_observation(raw, wrapped.observation_space)["grid"], flat["grid"])


def test_state_only_drops_the_grid() -> None:
    wrapped = PolicyObservation(StandIn(), grid=False)
    assert list(wrapped.observation_space.spaces) == ["state"]
    obs, _ = wrapped.reset(seed=1)
    assert set(obs) == {"state"} and wrapped.observation_space.contains(obs)


def test_bad_spaces_and_observations_are_named() -> None:
    env = StandIn()
    env.observation_space = spaces.Dict({"state": env.observation_space["state"]})
    with pytest.raises(InterfaceError, match=r"^env.observation_space: .*3-D 'grid'") as no_grid:
        PolicyObservation(env)
    assert isinstance(no_grid.value, TypeError)
    env.observation_space = spaces.Box(0, 1, (3,))
    with pytest.raises(InterfaceError, match=r"^env.observation_space: .*Dict space"):
        PolicyObservation(env)
    space = PolicyObservation(StandIn()).observation_space
    with pytest.raises(ConfigError, match=r"^observation.grid: missing") as missing:
        match_observation({"state": np.zeros(5, np.float32)}, space)
    assert missing.value.field == "observation.grid" and isinstance(missing.value, ValueError)
    with pytest.raises(ConfigError, match=r"^observation.grid: has shape .* the policy expects"):
        match_observation({"grid": np.zeros((4, 36, 15), np.uint8), "state": np.zeros(5, np.float32)}, space)


def test_sb3_check_env_warns_on_the_raw_grid_and_not_on_the_wrapped_one() -> None:
    from stable_baselines3.common.env_checker import check_env

    import negobs_gym  # noqa: F401 - registers the envs

    env = gym.make("negobs_gym/Braking-v1", overrides={"observation.source": "oracle"})
    with warnings.catch_warnings(record=True) as raw:
        warnings.simplefilter("always")
        check_env(env.unwrapped, warn=True)
    assert image_warnings(raw)  # the env's own (C, R, W) grid: SB3 takes it for a small image
    with warnings.catch_warnings(record=True) as wrapped:
        warnings.simplefilter("always")
        check_env(PolicyObservation(env.unwrapped), warn=True)
    assert image_warnings(wrapped) == []
    env.close()
