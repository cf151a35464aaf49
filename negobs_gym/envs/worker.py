"""The process side of :class:`~negobs_gym.envs.vector.PrefetchVecEnv`: one env served over a pipe.

Kept apart from the vector env so that a worker imports neither stable-baselines3 nor torch
(~190 MB of resident memory per process, and seconds of start-up, measured): the env constructor
travels with cloudpickle, and a failure travels back as text.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable
from typing import Any

import cloudpickle
import gymnasium as gym

from negobs_gym.errors import UnknownNameError

__all__ = ["EnvFactory", "WorkerFailure", "class_name", "serve"]

#: The commands :func:`serve` answers besides ``close``.
_COMMANDS = ("step", "reset", "method", "get_attr", "has_attr", "set_attr", "is_wrapped", "spaces")


class EnvFactory:
    """An env constructor pickled with cloudpickle (lambdas and closures work too)."""

    def __init__(self, make: Callable[[], gym.Env]) -> None:
        self.make = make

    def __getstate__(self) -> bytes:
        return cloudpickle.dumps(self.make)

    def __setstate__(self, state: bytes) -> None:
        self.make = cloudpickle.loads(state)


class WorkerFailure:
    """An exception raised in a worker, carried to the main process with its traceback."""

    def __init__(self, exc: BaseException) -> None:
        self.text = "".join(traceback.format_exception(exc))


def class_name(cls: type) -> str:
    """``module.qualname`` of a class: how a wrapper class is named to a worker (sending the class
    itself would make the worker import its module, e.g. stable-baselines3's ``Monitor``)."""
    return f"{cls.__module__}.{cls.__qualname__}"


def _is_wrapped(env: gym.Env, wrapper_name: str) -> bool:
    """Whether a wrapper of ``env`` is an instance of the class named ``wrapper_name``."""
    while isinstance(env, gym.Wrapper):
        if any(class_name(c) == wrapper_name for c in type(env).__mro__):
            return True
        env = env.env
    return False


def serve(remote: Any, parent_remote: Any, factory: EnvFactory) -> None:
    """Build the env, then answer commands until ``close``: ``step`` (no automatic reset),
    ``reset`` (seed, options), ``method``, ``get_attr``, ``set_attr``, ``is_wrapped`` (a
    :func:`class_name`), ``spaces``.
    An exception is sent back as a :class:`WorkerFailure`; an env that cannot be built answers
    every command with its failure."""
    parent_remote.close()
    broken: WorkerFailure | None = None
    try:
        env = factory.make()
    except Exception as exc:
        broken = WorkerFailure(exc)
    while True:
        try:
            cmd, data = remote.recv()
        except (EOFError, KeyboardInterrupt):
            break
        if cmd == "close":
            if broken is None:
                env.close()
            remote.close()
            break
        if broken is not None:
            remote.send(broken)
            continue
        try:
            if cmd == "step":
                out: Any = env.step(data)
            elif cmd == "reset":
                out = env.reset(seed=data[0], options=data[1])
            elif cmd == "method":
                out = env.get_wrapper_attr(data[0])(*data[1], **data[2])
            elif cmd == "get_attr":
                out = env.get_wrapper_attr(data)
            elif cmd == "has_attr":
                out = env.has_wrapper_attr(data)
            elif cmd == "set_attr":
                out = setattr(env, data[0], data[1])
            elif cmd == "is_wrapped":
                out = _is_wrapped(env, data)
            elif cmd == "spaces":
                out = (env.observation_space, env.action_space)
            else:
                raise UnknownNameError(f"worker command {cmd!r}: not one of {_COMMANDS}")
        except Exception as exc:  # carried to the main process, which raises it there
            out = WorkerFailure(exc)
        remote.send(out)
