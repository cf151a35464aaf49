"""A vector env whose resets do not stall the others: each slot keeps a spare process that resets
the slot's next episode while the current one runs.

SB3's ``SubprocVecEnv`` steps its workers in lockstep and resets a finished env inside its step,
so while one worker builds a new terrain and world (0.6-1.7 s on OffroadNav, by the machine's
speed) every other worker waits: with ~100-step episodes that is about a fifth of a 2-process run
(docs/notebook/performance.md, "Where the 2-process run loses"). :class:`PrefetchVecEnv` runs two processes
per slot. One steps the current episode; the other has already reset the next one, so a finished
episode is replaced at once and the process that ran it starts resetting the episode after, beside
the others' steps. (:class:`~negobs_gym.envs.build_ahead.BuildAheadVecEnv`, ``negobs train``'s
default, keeps one process per env and SB3's episodes, and builds a worker's next world while the
worker waits.)

Episodes are seeded explicitly so that the spare can start early: episode ``k`` of slot ``i`` is
reset with :func:`episode_seed` ``(base, i, k)``, ``base`` from :meth:`PrefetchVecEnv.seed`. A
slot's episode stream therefore depends on the base seed only, never on timing, and each episode
equals a single env reset with its seed (``tests/envs/test_vector.py``). (``SubprocVecEnv``
resets without a seed, from the env's generator, so the two give different episode streams.)
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from negobs_gym.envs.worker import EnvFactory, WorkerFailure, class_name, serve
from negobs_gym.errors import ConfigError, ResetNeeded, WorkerError

__all__ = ["PrefetchVecEnv", "episode_seed"]


def episode_seed(base_seed: int, slot: int, episode: int) -> int:
    """Seed of episode ``episode`` of slot ``slot`` (a 32-bit hash of the three)."""
    return int(np.random.SeedSequence([base_seed, slot, episode]).generate_state(1, np.uint32)[0])


class _Process:
    """One worker process and its pipe; at most one reset may be outstanding."""

    def __init__(self, ctx: Any, env_fn: Callable[[], gym.Env]) -> None:
        self.remote, work_remote = ctx.Pipe()
        self.process = ctx.Process(
            target=serve, args=(work_remote, self.remote, EnvFactory(env_fn)), daemon=True
        )
        self.process.start()
        work_remote.close()
        self._reset_pending = False
        self._reset_reply: Any = None

    def request(self, cmd: str, data: Any = None) -> Any:
        """Send a command and wait for its reply (after a pending reset's, which is kept)."""
        self._collect_reset()
        self.remote.send((cmd, data))
        return self._receive()

    def send_step(self, action: np.ndarray) -> None:
        self.remote.send(("step", action))

    def receive_step(self) -> Any:
        return self._receive()

    def start_reset(self, seed: int, options: dict | None = None) -> None:
        self._collect_reset()
        self._reset_reply = None  # an earlier reset's reply is superseded
        self.remote.send(("reset", (seed, options)))
        self._reset_pending = True

    def finish_reset(self) -> tuple[Any, dict]:
        """The reply of the last :meth:`start_reset` (waits for it if it is still running)."""
        self._collect_reset()
        reply, self._reset_reply = self._reset_reply, None
        if reply is None:
            raise ResetNeeded("finish_reset: no reset was started on this process (call start_reset first)")
        return reply

    def wait_for_reset(self) -> None:
        """Block until a started reset has finished (its reply is kept for :meth:`finish_reset`)."""
        self._collect_reset()

    def _collect_reset(self) -> None:
        if self._reset_pending:
            self._reset_pending = False
            self._reset_reply = self._receive()

    def _receive(self) -> Any:
        reply = self.remote.recv()
        if isinstance(reply, WorkerFailure):
            raise WorkerError(f"a PrefetchVecEnv worker failed:\n{reply.text}")
        return reply

    def close(self) -> None:
        if self._reset_pending and self.remote.poll(60):  # a reply larger than the pipe's buffer
            self.remote.recv()  # would block the worker before it reads "close"
        try:
            self.remote.send(("close", None))
        except (BrokenPipeError, EOFError, OSError):
            pass
        self.process.join(timeout=10)
        if self.process.is_alive():
            self.process.terminate()
        self.remote.close()


def _stack(obs: list[Any], space: spaces.Space) -> Any:
    if isinstance(space, spaces.Dict):
        return {key: np.stack([o[key] for o in obs]) for key in space.spaces}
    if isinstance(space, spaces.Tuple):
        return tuple(np.stack([o[k] for o in obs]) for k in range(len(space.spaces)))
    return np.stack(obs)


class PrefetchVecEnv(VecEnv):
    """SB3 ``VecEnv`` of ``len(env_fns)`` slots, two processes each (see the module docstring).

    ``seed(s)`` sets the base seed of the next :meth:`reset` (without it a random base is drawn).
    ``info`` follows ``SubprocVecEnv``: ``terminal_observation`` on finished steps,
    ``TimeLimit.truncated``; ``reset_infos`` holds each slot's latest reset info. ``set_attr`` and
    ``env_method`` reach both processes of a slot, and the spare then resets its prefetched episode
    again, so that (as with ``SubprocVecEnv``) the slot's next episode starts after the change; that
    costs a reset beside the steps per call and slot, so call them between updates (a curriculum
    step), not every step. ``get_attr`` asks the stepping process. Memory and start-up are those of
    ``2 * len(env_fns)`` envs.

    Raises:
        ConfigError: ``env_fns`` is empty (a ``ValueError``).
        WorkerError: A worker raised (its traceback is in the message; a ``RuntimeError``).
    """

    def __init__(self, env_fns: Sequence[Callable[[], gym.Env]], start_method: str | None = None) -> None:
        if len(env_fns) == 0:
            raise ConfigError("env_fns", "must hold at least one env constructor")
        if start_method is None:
            start_method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        ctx = mp.get_context(start_method)
        self._active = [_Process(ctx, fn) for fn in env_fns]
        self._spare = [_Process(ctx, fn) for fn in env_fns]
        self._episode = [0] * len(env_fns)
        self._base_seed: int | None = None
        self._base = 0  # base seed of the running episodes
        self._steps = 0  # steps of the vector env since it was made: its slots' scan clock
        self._started = False
        self.closed = False
        try:
            observation_space, action_space = self._active[0].request("spaces")
            # negobs envs with ObservationConfig.scan_clock = "env" cast on the vector's steps
            self._clocked = bool(self._active[0].request("has_attr", "sync_scan_clock"))
            super().__init__(len(env_fns), observation_space, action_space)
        except BaseException:
            self.close()
            raise

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Base seed of the next :meth:`reset`; returns the seeds of the slots' first episodes."""
        if seed is not None and not (isinstance(seed, (int, np.integer)) and seed >= 0):
            raise ConfigError("seed", f"must be None or an int >= 0, got {seed!r}")
        self._base_seed = None if seed is None else int(seed)
        if seed is None:
            return [None] * self.num_envs
        return [episode_seed(self._base_seed, i, 0) for i in range(self.num_envs)]

    def reset(self) -> Any:
        base = self._base_seed
        if base is None:
            base = int(np.random.SeedSequence().generate_state(1, np.uint32)[0])
        self._base_seed = None
        obs = []
        for i in range(self.num_envs):
            self._active[i].start_reset(episode_seed(base, i, 0), self._options[i] or None)
            self._spare[i].start_reset(episode_seed(base, i, 1))
            self._episode[i] = 0
        self._base = base
        for i in range(self.num_envs):
            o, self.reset_infos[i] = self._active[i].finish_reset()
            self._sync_clock(i)
            obs.append(o)
        self._reset_options()
        self._started = True
        return _stack(obs, self.observation_space)

    def step_async(self, actions: np.ndarray) -> None:
        if not self._started:
            raise ResetNeeded("PrefetchVecEnv: call reset() before step()")
        for proc, action in zip(self._active, actions, strict=True):
            proc.send_step(action)

    def step_wait(self) -> tuple[Any, np.ndarray, np.ndarray, list[dict]]:
        obs, rewards, dones, infos = [], [], [], []
        self._steps += 1
        for i in range(self.num_envs):
            o, reward, terminated, truncated, info = self._active[i].receive_step()
            done = bool(terminated or truncated)
            info = dict(info)
            info["TimeLimit.truncated"] = bool(truncated and not terminated)
            if done:
                info["terminal_observation"] = o
                o, self.reset_infos[i] = self._spare[i].finish_reset()
                self._active[i], self._spare[i] = self._spare[i], self._active[i]
                self._sync_clock(i)
                self._episode[i] += 1
                self._spare[i].start_reset(episode_seed(self._base, i, self._episode[i] + 1))
            obs.append(o)
            rewards.append(reward)
            dones.append(done)
            infos.append(info)
        return _stack(obs, self.observation_space), np.asarray(rewards), np.asarray(dones), infos

    def _sync_clock(self, slot: int) -> None:
        """Put the frames of slot ``slot``'s stepping process on the vector's step count: its
        spare reset the episode without stepping, so its own count lags the other slots'
        (``ObservationConfig.scan_clock = "env"``; ``NegObsEnv.sync_scan_clock``)."""
        if self._clocked:
            self._active[slot].request("method", ("sync_scan_clock", (self._steps,), {}))

    def wait_for_spares(self) -> None:
        """Block until every spare process has reset its episode (e.g. before timing a run: right
        after :meth:`reset` the spares are still building their first episodes)."""
        for proc in self._spare:
            proc.wait_for_reset()

    def episode_seeds(self) -> list[int]:
        """Seed of each slot's current episode."""
        return [episode_seed(self._base, i, k) for i, k in enumerate(self._episode)]

    def close(self) -> None:
        if self.closed:
            return
        for proc in self._active + self._spare:
            proc.close()
        self.closed = True

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [self._active[i].request("get_attr", attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for i in self._get_indices(indices):
            for proc in (self._active[i], self._spare[i]):
                proc.request("set_attr", (attr_name, value))
            self._reprefetch(i)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        out = []
        for i in self._get_indices(indices):
            self._spare[i].request("method", (method_name, method_args, method_kwargs))
            out.append(self._active[i].request("method", (method_name, method_args, method_kwargs)))
            self._reprefetch(i)
        return out

    def _reprefetch(self, slot: int) -> None:
        """Reset slot ``slot``'s next episode again in its spare (same seed), after a change that the
        episode's reset may read."""
        if self._started:
            self._spare[slot].start_reset(episode_seed(self._base, slot, self._episode[slot] + 1))

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        name = class_name(wrapper_class)
        return [self._active[i].request("is_wrapped", name) for i in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [self._active[i].request("method", ("render", (), {})) for i in range(self.num_envs)]
