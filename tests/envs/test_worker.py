"""The vector-env worker loop, served over a pipe in a thread (no process needed)."""

from __future__ import annotations

import multiprocessing as mp
import pickle
import threading

import gymnasium as gym
import numpy as np

from negobs_gym.envs.worker import EnvFactory, WorkerFailure, class_name, serve


def _serve(make):
    parent, child = mp.Pipe()
    spare_end, _ = mp.Pipe()  # serve closes the "parent remote" it is handed
    factory = pickle.loads(pickle.dumps(EnvFactory(make)))  # the constructor survives pickling
    thread = threading.Thread(target=serve, args=(child, spare_end, factory), daemon=True)
    thread.start()

    def ask(cmd, data=None):
        parent.send((cmd, data))
        return parent.recv()

    return ask, parent, thread


def test_serves_an_env_without_resetting_it_on_episode_end() -> None:
    ask, parent, thread = _serve(lambda: gym.wrappers.TimeLimit(gym.make("CartPole-v1").unwrapped, 2))
    obs_space, action_space = ask("spaces")
    assert obs_space.shape == (4,) and action_space.n == 2
    obs, _ = ask("reset", (3, None))
    same, _ = gym.make("CartPole-v1").reset(seed=3)
    assert np.array_equal(obs, same)
    ask("step", 1)
    _, _, _, truncated, _ = ask("step", 1)
    assert truncated  # the episode ended and the worker left it so: the vector env decides
    ask("set_attr", ("probe", 5))
    assert ask("get_attr", "probe") == 5
    assert ask("is_wrapped", class_name(gym.wrappers.TimeLimit))
    assert ask("is_wrapped", class_name(gym.Wrapper))  # a subclass counts, as with isinstance
    assert not ask("is_wrapped", class_name(gym.wrappers.RecordEpisodeStatistics))
    failure = ask("method", ("no_such_method", (), {}))
    assert isinstance(failure, WorkerFailure) and "no_such_method" in failure.text
    unknown = ask("fly")
    assert isinstance(unknown, WorkerFailure) and "UnknownNameError: worker command 'fly'" in unknown.text
    parent.send(("close", None))
    thread.join(timeout=10)
    assert not thread.is_alive()


def test_an_env_that_cannot_be_built_answers_every_command_with_its_failure() -> None:
    def broken():
        raise ValueError("no terrain")

    ask, parent, thread = _serve(broken)
    for cmd in ("spaces", "step"):
        reply = ask(cmd)
        assert isinstance(reply, WorkerFailure) and "no terrain" in reply.text
    parent.send(("close", None))
    thread.join(timeout=10)
    assert not thread.is_alive()


def test_factory_carries_closures() -> None:
    limit = 7
    factory = pickle.loads(pickle.dumps(EnvFactory(lambda: gym.make("CartPole-v1", max_episode_steps=limit))))
    assert factory.make().spec.max_episode_steps == 7
