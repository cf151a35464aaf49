"""Every way of building an env runs the same spec: ranged start speeds and time limits survive.

The scenario spec is the one description of an episode; registry, direct construction, the env
factory, a TOML file and the commands' ``--set`` all apply overrides to it, and none of them
replaces a setting it was not asked to change.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.cli.common import task_env_or_exit
from negobs_gym.envs import BrakingEnv, NegObsEnv, make_env
from negobs_gym.registration import ENV_SPECS, SCENES
from negobs_gym.spec import Range, apply_overrides, load_scenario, scenario_names, spec_to_toml

#: A ranged start speed and a time limit that no shipped scene has, on the oracle grid (cheap).
RANGED = ["start.speed_mps=[4.0, 6.0]", "episode.time_limit_s=12.5", "observation.source=oracle"]
SPEED, LIMIT_S = Range(low=4.0, high=6.0), 12.5


def _ranged_spec():
    return apply_overrides(load_scenario("braking_v1"), RANGED)


def _build(path: str, tmp_path: Path) -> gym.Env:
    if path == "registry":
        return gym.make("negobs_gym/Braking-v1", overrides=RANGED)
    if path == "registry_mapping":
        mapping = {
            "start.speed_mps": [4.0, 6.0],
            "episode.time_limit_s": LIMIT_S,
            "observation.source": "oracle",
        }
        return gym.make("negobs_gym/Braking-v1", overrides=mapping)
    if path == "direct":
        return BrakingEnv(overrides=RANGED)
    if path == "direct_spec":
        return NegObsEnv(scenario=_ranged_spec())
    if path == "factory":
        return make_env("braking_v1", RANGED)
    if path == "toml":
        scene = tmp_path / "ranged.toml"
        scene.write_text(spec_to_toml(_ranged_spec()), encoding="utf-8")
        return make_env(str(scene))
    if path == "set":  # a command's --env and --set
        return task_env_or_exit(argparse.ArgumentParser(), "negobs_gym/Braking-v1", None, RANGED)
    raise AssertionError(path)


@pytest.mark.parametrize(
    "path", ["registry", "registry_mapping", "direct", "direct_spec", "factory", "toml", "set"]
)
def test_ranged_start_speed_and_time_limit_survive_every_construction_path(path: str, tmp_path: Path) -> None:
    env = _build(path, tmp_path)
    spec = env.unwrapped.scenario
    assert spec.start.speed_mps == SPEED  # still a range, not its low end
    assert spec.episode.time_limit_s == LIMIT_S and spec.episode.max_episode_steps == 125
    assert spec == _ranged_spec()
    speeds = set()
    for seed in range(3):  # each reset draws its own start speed from the range
        _, info = env.reset(seed=seed)
        assert 3.5 < info["speed_mps"] < 6.5
        speeds.add(round(info["speed_mps"], 3))
    assert len(speeds) == 3
    env.close()


@pytest.mark.parametrize("env_id", [row[0] for row in ENV_SPECS])
def test_each_registered_env_runs_its_shipped_scene(env_id: str) -> None:
    env = gym.make(env_id)
    assert env.unwrapped.scenario == load_scenario(SCENES[env_id])
    env.close()


@pytest.mark.parametrize("name", scenario_names())
def test_each_shipped_scene_builds_an_env_from_its_spec(name: str) -> None:
    env = make_env(name)
    assert env.unwrapped.scenario == load_scenario(name)
    assert env.observation_space["grid"].shape == env.unwrapped.scenario.observation.shape
    env.close()


def test_a_braking_campaigns_episodes_keep_the_ranged_start_speed_and_time_limit() -> None:
    """The campaign path: its episodes run their scene with the campaign's overrides."""
    from negobs_gym.eval.braking_campaign import (
        BrakingCampaignConfig,
        episode_overrides,
        episodes,
        scene_name,
    )

    config = BrakingCampaignConfig(
        scenarios=("ditch",), drivers=("reckless",), seeds=2, overrides=tuple(RANGED)
    )
    for episode in episodes(config):
        env = make_env(scene_name(episode.args["scenario"]), episode_overrides(episode.args))
        spec = env.unwrapped.scenario
        assert spec.start.speed_mps == SPEED and spec.episode.time_limit_s == LIMIT_S
        _, info = env.reset(seed=episode.args["seed"])
        assert 3.5 < info["speed_mps"] < 6.5
        env.close()
