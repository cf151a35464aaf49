"""Training envs as Ray actors (``negobs train --ray``): the same seeds give the same rollouts as
the local vector env, and the same trained weights; without ray, a clear error."""

from __future__ import annotations

import dataclasses
import functools
import sys
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.errors import MissingDependencyError
from negobs_gym.policies.config import TrainConfig
from negobs_gym.policies.training import make_training_env

#: Braking-v1 on the oracle grid with 1 s episodes: 25 steps hold several episode ends and resets.
OVERRIDES = ("observation.source=oracle", "episode.time_limit_s=1.0")


def _rollout(venv, steps: int = 25) -> list:
    """Observations, rewards (as float32: SB3's DummyVecEnv stores them so, SubprocVecEnv as
    float64), dones and final observations of ``steps`` random actions from seed 5."""
    venv.seed(5)
    frames: list = [venv.reset()]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (venv.num_envs, *venv.action_space.shape)).astype(np.float32)
        obs, rewards, dones, infos = venv.step(actions)
        finals = [info.get("terminal_observation") for info in infos]
        frames.append((obs, rewards.astype(np.float32), dones, finals))
    venv.close()
    return frames


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if a is None or b is None:
        return a is b
    return np.array_equal(a, b)


def test_without_ray_the_error_names_the_extra(monkeypatch) -> None:
    from negobs_gym.policies.ray_envs import RayVecEnv

    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(MissingDependencyError, match=r"negobs_gym\[ray\]"):
        RayVecEnv([functools.partial(make_training_env, "negobs_gym/Braking-v1", OVERRIDES)])


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray instance for the module (starting one takes ~10-20 s on 2 cores)."""
    ray = pytest.importorskip("ray")
    from negobs_gym.policies.ray_envs import ray_session

    with ray_session(cpus=2):
        yield ray


@pytest.mark.slow
def test_ray_actors_give_the_local_vector_envs_rollouts(local_ray) -> None:
    from stable_baselines3.common.vec_env import DummyVecEnv

    from negobs_gym.policies.ray_envs import RayVecEnv

    thunk = functools.partial(make_training_env, "negobs_gym/Braking-v1", OVERRIDES)
    local = _rollout(DummyVecEnv([thunk] * 2))
    on_ray = _rollout(RayVecEnv([thunk] * 2))
    assert sum(int(frame[2].sum()) for frame in local[1:]) >= 2  # episodes ended and reset
    assert _same(local, on_ray)
    ray_env = RayVecEnv([thunk])  # the VecEnv methods SB3 calls reach the actor's env
    assert ray_env.get_attr("grid_shape") == [thunk().grid_shape]
    assert ray_env.has_attr("grid_shape") and not ray_env.has_attr("no_such_attribute")
    ray_env.close()
    assert local_ray.is_initialized()  # an instance it did not start is left running


@pytest.mark.slow
def test_training_on_ray_trains_the_local_weights(local_ray, tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    from negobs_gym.policies.training import train

    config = TrainConfig(
        env="negobs_gym/Braking-v1",
        overrides=OVERRIDES,
        steps=64,
        n_steps=32,
        batch_size=32,
        eval_every=0,
        eval_episodes=1,
        checkpoint_every=0,
        progress=False,
    )
    local = train(config, tmp_path / "local")
    remote = train(dataclasses.replace(config, vec_env="ray"), tmp_path / "ray")
    weights = [PPO.load(r.model_path, device="cpu").policy.state_dict() for r in (local, remote)]
    assert all(np.array_equal(weights[0][k].numpy(), weights[1][k].numpy()) for k in weights[0])
    figures = [{k: v for k, v in r.last_eval.items() if k != "wall_s"} for r in (local, remote)]
    assert figures[0].keys() == figures[1].keys()
    assert all(np.array_equal(figures[0][k], figures[1][k], equal_nan=True) for k in figures[0])
