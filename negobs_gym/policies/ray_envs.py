"""Training envs as Ray actors: ``negobs train --ray [ADDRESS]`` (``TrainConfig.vec_env="ray"``).

:class:`RayVecEnv` is stable-baselines3's ``SubprocVecEnv`` with each env in a Ray actor instead
of a local process, on a cluster or on a local instance, as the campaigns run their episodes
(:mod:`negobs_gym.eval.campaign`). An actor does what a ``SubprocVecEnv`` worker does, step for
step (an episode's end resets it and hands back its last observation in the info), so the same
seeds give the same rollouts as the local vector envs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn
from stable_baselines3.common.vec_env.subproc_vec_env import _stack_obs

from negobs_gym.eval.campaign import ray_session

__all__ = ["EnvActor", "RayVecEnv", "ray_session"]


class EnvActor:
    """One env in a Ray actor: what a ``SubprocVecEnv`` worker does, method by method."""

    def __init__(self, env_fn: Callable[[], gym.Env]) -> None:
        import negobs_gym  # noqa: F401 - registers the env ids in the actor's process

        self.env = env_fn()
        self.reset_info: dict[str, Any] = {}

    def spaces(self) -> tuple[gym.Space, gym.Space]:
        return self.env.observation_space, self.env.action_space

    def step(self, action: np.ndarray) -> tuple[Any, SupportsFloat, bool, dict[str, Any], dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        done = terminated or truncated
        info["TimeLimit.truncated"] = truncated and not terminated
        if done:
            info["terminal_observation"] = observation
            observation, self.reset_info = self.env.reset()
        return observation, reward, done, info, self.reset_info

    def reset(self, seed: int | None, options: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
        observation, self.reset_info = self.env.reset(seed=seed, **({"options": options} if options else {}))
        return observation, self.reset_info

    def render(self) -> Any:
        return self.env.render()

    def get_attr(self, name: str) -> Any:
        return self.env.get_wrapper_attr(name)

    def has_attr(self, name: str) -> bool:
        try:
            self.env.get_wrapper_attr(name)
        except AttributeError:
            return False
        return True

    def set_attr(self, name: str, value: Any) -> None:
        setattr(self.env, name, value)

    def env_method(self, name: str, args: tuple, kwargs: dict[str, Any]) -> Any:
        return self.env.get_wrapper_attr(name)(*args, **kwargs)

    def is_wrapped(self, wrapper_class: type[gym.Wrapper]) -> bool:
        from stable_baselines3.common.env_util import is_wrapped

        return is_wrapped(self.env, wrapper_class)

    def close(self) -> None:
        self.env.close()


class RayVecEnv(VecEnv):
    """``len(env_fns)`` envs, each in a Ray actor (one CPU each); ``address`` as
    :func:`ray_session`. Ray is started here unless it runs already, and shut down by
    :meth:`close` if so."""

    def __init__(self, env_fns: Sequence[Callable[[], gym.Env]], address: str = "") -> None:
        self._session = ray_session(address, cpus=len(env_fns))
        self._ray = self._session.__enter__()
        self.closed = False
        self.waiting = False
        try:
            remote = self._ray.remote(num_cpus=1)(EnvActor)
            self.actors = [remote.remote(fn) for fn in env_fns]
            observation_space, action_space = self._get(self.actors[0].spaces.remote())
        except BaseException:
            self._session.__exit__(None, None, None)
            raise
        super().__init__(len(env_fns), observation_space, action_space)
        self._pending: list[Any] = []

    def _get(self, refs: Any) -> Any:
        return self._ray.get(refs)

    def step_async(self, actions: np.ndarray) -> None:
        self._pending = [actor.step.remote(a) for actor, a in zip(self.actors, actions, strict=True)]
        self.waiting = True

    def step_wait(self) -> VecEnvStepReturn:
        results = self._get(self._pending)
        self.waiting = False
        obs, rewards, dones, infos, reset_infos = zip(*results, strict=True)
        self.reset_infos = list(reset_infos)
        for info in infos:  # Ray hands arrays back read-only; torch warns on those
            if "terminal_observation" in info:
                info["terminal_observation"] = _writable(info["terminal_observation"])
        return _stack_obs(obs, self.observation_space), np.stack(rewards), np.stack(dones), infos  # type: ignore[return-value]

    def reset(self) -> VecEnvObs:
        refs = [a.reset.remote(self._seeds[i], self._options[i]) for i, a in enumerate(self.actors)]
        obs, reset_infos = zip(*self._get(refs), strict=True)
        self.reset_infos = list(reset_infos)
        self._reset_seeds()  # seeds and options are used once, as SB3's vector envs do
        self._reset_options()
        return _stack_obs(obs, self.observation_space)

    def close(self) -> None:
        if self.closed:
            return
        if self.waiting:
            self._get(self._pending)
        self._get([a.close.remote() for a in self.actors])
        for actor in self.actors:
            self._ray.kill(actor)
        self.closed = True
        self._session.__exit__(None, None, None)

    def get_images(self) -> Sequence[np.ndarray | None]:
        return self._get([a.render.remote() for a in self.actors])

    def _targets(self, indices: VecEnvIndices) -> list[Any]:
        return [self.actors[i] for i in self._get_indices(indices)]

    def has_attr(self, attr_name: str) -> bool:
        return all(self._get([a.has_attr.remote(attr_name) for a in self.actors]))

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return self._get([a.get_attr.remote(attr_name) for a in self._targets(indices)])

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self._get([a.set_attr.remote(attr_name, value) for a in self._targets(indices)])

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        refs = [a.env_method.remote(method_name, method_args, method_kwargs) for a in self._targets(indices)]
        return self._get(refs)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return self._get([a.is_wrapped.remote(wrapper_class) for a in self._targets(indices)])


def _writable(observation: Any) -> Any:
    """``observation`` (an array or a dict of arrays) with each array copied writable."""
    if isinstance(observation, dict):
        return {k: np.array(v) for k, v in observation.items()}
    return np.array(observation)
