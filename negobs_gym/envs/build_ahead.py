"""SB3's ``SubprocVecEnv`` whose idle workers build their next episode's world ahead of the reset.

In a lockstep vector env the workers wait often: for the policy's update between rollouts (with
PPO on 2 cores, ~30 % of a training run), for an evaluation, and for every other worker's reset.
A reset onto a new terrain is mostly building the world (terrain, PyBullet heightfield, settling:
~1 s on OffroadNav), and the next reset's world is known as soon as the current episode starts: a
reset without a seed draws from the env's generator, which steps do not touch. So a worker that has
waited ``idle_s`` for a command calls the env's
:meth:`~negobs_gym.envs.base.NegObsEnv.build_ahead`, and the reset that ends its episode takes the
world like a kept one (docs/performance.md, "Resets"). Built ahead or not, an episode is the same
bit for bit, so the episode stream equals ``SubprocVecEnv``'s (``tests/envs/test_build_ahead.py``);
only where the time goes changes. Each worker holds one more world in memory.

The workers run SB3's own worker loop on a pipe whose ``recv`` first waits ``idle_s`` and then,
if no command came, builds; everything else (commands, auto-reset, ``terminal_observation``) is
SB3's.
"""

from __future__ import annotations

import logging
import math
import multiprocessing as mp
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
from stable_baselines3.common.vec_env import SubprocVecEnv, VecEnv
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper
from stable_baselines3.common.vec_env.subproc_vec_env import _worker

from negobs_gym.errors import ConfigError

__all__ = ["BuildAheadVecEnv"]

log = logging.getLogger(__name__)


class _IdlePipe:
    """A worker's end of the pipe whose ``recv``, after ``idle_s`` without a command, runs ``on_idle``
    before it waits on."""

    def __init__(self, conn: Any, idle_s: float, on_idle: Callable[[], None]) -> None:
        self._conn = conn
        self._idle_s = idle_s
        self._on_idle = on_idle

    def recv(self) -> Any:
        if not self._conn.poll(self._idle_s):
            self._on_idle()
        return self._conn.recv()

    def send(self, obj: Any) -> None:
        self._conn.send(obj)

    def close(self) -> None:
        self._conn.close()


class _Builder:
    """Makes the worker's env and builds its next world when asked; an env without
    ``build_ahead`` (not a negobs env) is left alone."""

    def __init__(self, make: Callable[[], gym.Env]) -> None:
        self._make = make
        self._build: Callable[[], bool] | None = None

    def make(self) -> gym.Env:
        env = self._make()
        try:
            self._build = env.get_wrapper_attr("build_ahead")
        except AttributeError:
            self._build = None
        return env

    def __call__(self) -> None:
        if self._build is None:
            return
        try:
            self._build()
        except Exception:  # the reset that needs the world builds it again and raises there
            log.warning("building the next world ahead failed; the reset will build it", exc_info=True)


def _build_ahead_worker(remote: Any, parent_remote: Any, env_fn: CloudpickleWrapper, idle_s: float) -> None:
    """SB3's worker loop over a pipe that builds the next world when idle."""
    builder = _Builder(env_fn.var)
    _worker(_IdlePipe(remote, idle_s, builder), parent_remote, CloudpickleWrapper(builder.make))


class BuildAheadVecEnv(SubprocVecEnv):
    """``SubprocVecEnv`` (same commands, same episodes) whose workers build their next world when
    they have waited ``idle_s`` seconds for a command.

    Args:
        env_fns: Env constructors, one per worker process.
        start_method: ``multiprocessing`` start method (SB3's default: forkserver where available).
        idle_s: How long a worker waits for a command before it builds; longer than the gap
            between two steps of a rollout (a few ms to tens of ms), shorter than a policy update
            or another worker's reset (~1 s).
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        start_method: str | None = None,
        idle_s: float = 0.1,
    ) -> None:
        if not (isinstance(idle_s, (int, float)) and math.isfinite(idle_s) and idle_s > 0):
            raise ConfigError("idle_s", f"must be a finite number of seconds > 0, got {idle_s!r}")
        # SubprocVecEnv.__init__ with the worker above: SB3 names its worker inside __init__
        self.waiting = False
        self.closed = False
        if start_method is None:
            start_method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        ctx = mp.get_context(start_method)
        self.remotes, self.work_remotes = zip(*[ctx.Pipe() for _ in env_fns], strict=True)
        self.processes = []
        for work_remote, remote, env_fn in zip(self.work_remotes, self.remotes, env_fns, strict=True):
            args = (work_remote, remote, CloudpickleWrapper(env_fn), float(idle_s))
            process = ctx.Process(target=_build_ahead_worker, args=args, daemon=True)
            process.start()
            self.processes.append(process)
            work_remote.close()
        self.remotes[0].send(("get_spaces", None))
        observation_space, action_space = self.remotes[0].recv()
        VecEnv.__init__(self, len(env_fns), observation_space, action_space)
