"""The spec-driven env: time limits, hooks read from the spec, settings reachable, grid sources."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.envs import NegObsEnv
from negobs_gym.envs.scenarios import BrakingEnv
from negobs_gym.envs.sources import DetectorSource, GridSource, OracleSource, make_grid_source
from negobs_gym.errors import ConfigError, NegobsError, ResetNeeded
from negobs_gym.spec import ObservationConfig, spec_from_toml

BRAKE = np.array([-1.0, 0.0], np.float32)
ORACLE = ObservationConfig(source="oracle")
ORACLE_GRID = {"observation.source": "oracle"}

# flat track, a ditch 10 m ahead, 25 km/h: a full brake stops 3.8 m after the start
STOP_SCENE = """
name = "stop_here"
terminations = ["entered_negative_obstacle", "stopped"]
[terrain.course]
length_m = 40.0
[terrain.course.roughness]
slope_amplitude_m = 0.0
bump_amplitude_m = 0.0
fine_amplitude_m = 0.0
rut_depth_m = 0.0
[[obstacles]]
kind = "ditch"
length_m = 1.0
width_m = 3.0
station_m = 14.0
[start]
speed_mps = 6.944444444444445
[task]
kind = "stop_before_hazard"
[reward]
stopped = 50.0
[observation]
source = "oracle"
"""


def _steps_until_done(env: gym.Env, limit: int = 1000) -> tuple[int, bool, bool]:
    env.reset(seed=0)
    for k in range(1, limit + 1):
        _, _, terminated, truncated, _ = env.step(BRAKE)
        if terminated or truncated:
            return k, terminated, truncated
    raise AssertionError("episode did not end")


@pytest.mark.parametrize("make", ["registry", "direct"])
def test_overridden_time_limit_is_honoured_however_the_env_is_made(make: str) -> None:
    # standing still: only the limit ends it
    changes = {**ORACLE_GRID, "episode.time_limit_s": 0.8, "start.speed_mps": 0.0}
    if make == "registry":
        env = gym.make("negobs_gym/Braking-v1", overrides=changes)
    else:
        env = BrakingEnv(overrides=changes)
    assert _steps_until_done(env) == (8, False, True)
    env.close()


def test_the_removed_config_argument_names_the_new_way() -> None:
    with pytest.raises(ConfigError, match="overrides="):
        BrakingEnv(ORACLE)


def test_spec_time_limit_truncates_a_directly_built_env() -> None:
    spec = spec_from_toml(STOP_SCENE.replace("[start]", "[episode]\ntime_limit_s = 0.5\n[start]"))
    env = NegObsEnv(scenario=dataclasses.replace(spec, terminations=()))
    assert _steps_until_done(env) == (5, False, True)
    env.close()


def test_registered_time_limits_come_from_the_specs() -> None:
    for env_id, steps in (
        ("negobs_gym/Braking-v0", 150),
        ("negobs_gym/Braking-v1", 150),
        ("negobs_gym/OffroadNav-v0", 600),
    ):
        env = gym.make(env_id)
        assert env.unwrapped.scenario.episode.max_episode_steps == steps
        assert env.spec.max_episode_steps is None  # no second, registry-side limit to disagree with
        env.close()


def test_stopping_before_the_ditch_is_rewarded_once_and_ends_the_episode() -> None:
    env = NegObsEnv(scenario=spec_from_toml(STOP_SCENE))
    _, info = env.reset(seed=0)
    assert 8.0 < info["distance_to_negative_ahead_m"] < 12.0
    paid = []
    for _ in range(60):
        _, reward, terminated, truncated, info = env.step(BRAKE)
        paid.append(info["rewards"]["stopped"])
        assert reward == pytest.approx(sum(info["rewards"].values()))
        if terminated:
            break
    assert terminated and not truncated and info["termination"] == ["stopped"]
    assert paid.count(50.0) == 1 and paid[-1] == 50.0
    assert info["stopped"] and info["speed_mps"] < 0.1 and info["distance_to_negative_ahead_m"] > 4.0
    env.close()


def test_braking_v0_keeps_its_terrain_draws_and_has_no_stopping_reward() -> None:
    spec = BrakingEnv.default_spec()
    assert spec.start.speed_mps == pytest.approx(25 / 3.6) and spec.reward.stopped == 50.0
    v0 = gym.make("negobs_gym/Braking-v0", overrides=ORACLE_GRID)
    v1 = gym.make("negobs_gym/Braking-v1", overrides=ORACLE_GRID)
    _, i0 = v0.reset(seed=7)
    _, i1 = v1.reset(seed=7)
    assert i0["distance_to_negative_ahead_m"] == i1["distance_to_negative_ahead_m"]
    assert "stopped" not in v0.unwrapped.scenario.terminations and v0.unwrapped.scenario.reward.stopped == 0.0
    assert "stopped" in v1.unwrapped.scenario.terminations and v1.unwrapped.scenario.reward.stopped > 0
    v0.close()
    v1.close()


def test_step_before_reset_raises_reset_needed() -> None:
    env = BrakingEnv(overrides=ORACLE_GRID)
    with pytest.raises(ResetNeeded, match="reset"):
        env.step(BRAKE)
    with pytest.raises(RuntimeError):  # also a RuntimeError, as gymnasium users expect
        env.hazard_state()
    assert issubclass(ResetNeeded, NegobsError)
    env.close()


def test_ins_noise_physics_and_render_settings_reach_the_episode() -> None:
    spec = spec_from_toml(
        STOP_SCENE + "[ins]\nposition_noise_m = 0.5\n[physics]\ntime_step_s = 0.008333333333333333\n"
        "[render]\nheight_px = 240\n"
    )
    env = NegObsEnv(scenario=spec, render_mode="rgb_array")
    env.reset(seed=1)
    assert env._substeps == 12  # 1/120 s physics at 10 Hz control
    assert env.vehicle.world.config.time_step_s == pytest.approx(1 / 120)
    vehicle = env.vehicle
    assert vehicle.config.ins_position_noise_m == 0.5
    offsets = [
        np.hypot(vehicle.pose().x - vehicle.true_pose().x, vehicle.pose().y - vehicle.true_pose().y)
        for _ in range(20)
    ]
    assert 0.1 < np.mean(offsets) < 1.5
    assert env.render().shape[0] == 240
    env.close()


def test_grid_sources_share_one_interface() -> None:
    assert isinstance(make_grid_source(ORACLE), OracleSource)
    assert isinstance(make_grid_source(ObservationConfig()), DetectorSource)
    for source in (make_grid_source(ORACLE), make_grid_source(ObservationConfig())):
        assert isinstance(source, GridSource)
        assert source.space().shape == ORACLE.shape and source.space().dtype == np.uint8
    env = NegObsEnv(scenario=spec_from_toml(STOP_SCENE))
    obs, _ = env.reset(seed=0)
    assert env.observation_space["grid"] == env._grid_source.space()
    assert obs["grid"][0].any()  # the oracle shows the ditch 10 m ahead
    env.close()


def test_a_scenario_is_required() -> None:
    with pytest.raises(ConfigError, match="scenario"):
        NegObsEnv()


def test_distance_ahead_sees_an_obstacle_wider_than_the_wheels_strip():
    # a 6 m trench across the whole track has no outline vertex in front of the wheels: the distance
    # comes from its edges clipped to the strip, the same as for a 1 m wide ditch at that station
    gaps = []
    for width_m in (1.0, 6.0):
        scene = STOP_SCENE.replace("width_m = 3.0", f"width_m = {width_m}")
        env = NegObsEnv(scenario=spec_from_toml(scene), overrides=ORACLE_GRID)
        _, info = env.reset(seed=0)
        env.close()
        gaps.append(info["distance_to_negative_ahead_m"])
    assert 9.0 < gaps[0] < 11.0  # ditch at station 14 m, the bumper ~3.9 m ahead of the start
    assert gaps[1] == pytest.approx(gaps[0], abs=1e-3)
