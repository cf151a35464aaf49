"""OffroadNav-v1: the route in the state, the obstacle channels, a cost for being trapped."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.core.geometry import vehicle_to_world_xy
from negobs_gym.envs.observation import state_fields, state_space
from negobs_gym.envs.outcome import StepOutcome
from negobs_gym.envs.rewards import reward_terms
from negobs_gym.envs.scenarios import OffroadNavEnv, OffroadNavV1Env
from negobs_gym.errors import ConfigError
from negobs_gym.sim.events import StepEvents
from negobs_gym.spec import ObservationConfig, RewardConfig

ORACLE_GRID = {"observation.source": "oracle"}
#: ... on the shortest winding course (60 m: a world builds ~4x faster); what the tests below check
#: does not depend on the course's length
SHORT_ORACLE = {**ORACLE_GRID, "terrain.params.length_m": 60.0}


def test_v1_state_holds_the_route_points_on_the_centre_line() -> None:
    env = gym.make("negobs_gym/OffroadNav-v1", overrides=SHORT_ORACLE)
    obs, info = env.reset(seed=4)
    assert env.observation_space["state"].shape == (11,)
    assert env.observation_space["grid"].shape == (2, 36, 16)
    names = state_fields(env.unwrapped.scenario.observation)
    assert names[5:] == (
        "route_5_x_m",
        "route_5_y_m",
        "route_10_x_m",
        "route_10_y_m",
        "route_15_x_m",
        "route_15_y_m",
    )
    track = env.unwrapped.terrain.track
    for step in range(40):
        obs, _, terminated, truncated, info = env.step(np.array([0.6, 0.3 * np.sin(step / 5)], np.float32))
        assert env.observation_space.contains(obs)
        pose = info["pose"]
        route_v = obs["state"][5:].reshape(3, 2).astype(np.float64)
        route_w = vehicle_to_world_xy(route_v, pose[:2], pose[5])
        expected, _ = track.pose_at(info["station_m"] + np.array([5.0, 10.0, 15.0]))
        np.testing.assert_allclose(route_w, expected, atol=1e-3)  # float32 state
        assert not (terminated or truncated)
    env.close()


def test_v1_keeps_v0_terrain_draws() -> None:
    v0 = OffroadNavEnv(overrides=SHORT_ORACLE)
    v1 = OffroadNavV1Env(overrides=SHORT_ORACLE)
    v0.reset(seed=11)
    v1.reset(seed=11)
    assert [o.outline_xy_m.tobytes() for o in v0.terrain.negative_obstacles] == [
        o.outline_xy_m.tobytes() for o in v1.terrain.negative_obstacles
    ]
    assert v1.scenario.reward.trapped == -50.0 and v0.scenario.reward.trapped == 0.0
    assert v1.scenario.reward.stopped == -50.0 and "stopped" in v1.scenario.terminations
    assert v1.scenario.observation.oracle_range_m == 14.0
    assert "stopped" not in v0.scenario.terminations
    v0.close()
    v1.close()


def test_v1_ends_when_the_car_stands_still() -> None:
    env = OffroadNavV1Env(overrides=SHORT_ORACLE)
    env.reset(seed=2)
    steps, terminated = 0, False
    while not terminated and steps < 40:
        _, _, terminated, _, info = env.step(np.array([-1.0, 0.0], np.float32))
        steps += 1
    assert terminated and info["termination"] == ["stopped"] and steps <= 12  # 1 s at 10 Hz (+ settling)
    env.close()


def test_trapped_costs_its_weight_once_per_event() -> None:
    config = RewardConfig(trapped=-50.0)
    free = reward_terms(config, StepOutcome(events=StepEvents()), stop_rewarded=False)
    stuck = reward_terms(config, StepOutcome(events=StepEvents(trapped=True)), stop_rewarded=False)
    assert free["trapped"] == 0.0 and stuck["trapped"] == -50.0
    assert reward_terms(RewardConfig(), StepOutcome(events=StepEvents(trapped=True)), False)["trapped"] == 0.0


def test_state_bounds_cover_the_route_and_bad_routes_are_refused() -> None:
    space = state_space(ObservationConfig(route_points_m=(5.0, 20.0)))
    assert space.shape == (9,) and space.high[-1] == pytest.approx(30.0)
    for bad in ((10.0, 5.0), (5.0, 5.0), (-1.0,), (float("nan"),)):
        with pytest.raises(ConfigError, match="route_points_m"):
            ObservationConfig(route_points_m=bad)
    for bad in (0.0, float("inf")):
        with pytest.raises(ConfigError, match="oracle_range_m"):
            ObservationConfig(oracle_range_m=bad)
    with pytest.raises(ConfigError, match="trapped"):
        RewardConfig(trapped=float("inf"))


def test_goal_approach_pays_the_capped_distance_to_the_goal_it_gains() -> None:
    overrides = {**SHORT_ORACLE, "reward.goal_approach": 2.0, "reward.goal_approach_radius_m": 1000.0}
    env = gym.make("negobs_gym/OffroadNav-v1", overrides=overrides)
    _, info = env.reset(seed=3)
    goal = np.asarray(env.unwrapped.terrain.goal_xy_m)
    gap = float(np.hypot(*(info["pose"][:2] - goal)))
    paid = []
    for _ in range(15):
        _, reward, _, _, info = env.step(np.array([0.6, 0.0], np.float32))
        now = float(np.hypot(*(info["pose"][:2] - goal)))
        assert info["rewards"]["goal_approach"] == pytest.approx(2.0 * (gap - now))
        assert reward == pytest.approx(sum(info["rewards"].values()))
        paid.append(info["rewards"]["goal_approach"])
        gap = now
    assert sum(paid) > 0  # driving down the course closes on its goal
    env.close()
    far = gym.make("negobs_gym/OffroadNav-v1", overrides={**SHORT_ORACLE, "reward.goal_approach": 2.0})
    far.reset(seed=3)  # the start lies beyond the default 15 m radius: nothing is paid there
    _, _, _, _, info = far.step(np.array([0.6, 0.0], np.float32))
    assert info["rewards"]["goal_approach"] == 0.0
    far.close()
    with pytest.raises(ConfigError, match="goal_approach_radius_m"):
        RewardConfig(goal_approach_radius_m=0.0)
