"""The env factory: a negobs env from an env argument (id, scene name, TOML path or spec) plus overrides.

Every command, campaign and training run builds its envs here, so ``--set`` paths, registered ids
and scenario files mean the same everywhere.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym

from negobs_gym.envs.base import NegObsEnv
from negobs_gym.errors import ConfigError
from negobs_gym.spec import ScenarioSpec, scenario_names, spec_for_env
from negobs_gym.spec.overrides import Overrides

__all__ = ["GRID_SOURCE_NAMES", "make_env", "registered_negobs_env", "source_overrides"]

#: Names a command's ``--source`` takes: the spec's ``observation.source`` values, and ``state``
#: (a policy sees no grid; the env computes the cheapest one, the oracle's, which it ignores).
GRID_SOURCE_NAMES: tuple[str, ...] = ("detector", "oracle", "pem", "state")


def registered_negobs_env(env_id: str) -> type[NegObsEnv] | None:
    """The :class:`NegObsEnv` subclass that ``gymnasium.make(env_id)`` builds; None when ``env_id``
    is not a registered id (a scenario name or TOML path, for the caller to try).

    Raises:
        ConfigError: ``env_id`` is registered but makes another env (field ``env``).
    """
    if env_id not in gym.registry:
        return None
    from gymnasium.envs.registration import load_env_creator  # gymnasium's own loader

    creator = load_env_creator(gym.spec(env_id).entry_point)
    if not (isinstance(creator, type) and issubclass(creator, NegObsEnv)) or creator.default_scenario is None:
        raise ConfigError("env", f"{env_id!r} is not a negobs_gym env (its observation has no grid)")
    return creator


def source_overrides(source: str | None) -> list[str]:
    """The ``--set`` assignment of a command's ``--source`` (none for None: the spec's own)."""
    if source is None:
        return []
    if source not in GRID_SOURCE_NAMES:
        raise ConfigError("source", f"must be one of {GRID_SOURCE_NAMES}, got {source!r}")
    return [f"observation.source={'oracle' if source == 'state' else source}"]


def make_env(env: str | ScenarioSpec, overrides: Overrides = (), render_mode: str | None = None) -> gym.Env:
    """The env named by ``env`` with its scenario changed by ``overrides``, rendering in ``render_mode``.

    ``env`` is a registered id (built through ``gymnasium.make``, with its wrappers), a shipped
    scenario's name, a scenario TOML file or a :class:`~negobs_gym.spec.ScenarioSpec`.
    ``overrides`` are ``KEY.PATH=VALUE`` texts (the commands' ``--set``) or a mapping
    (:func:`negobs_gym.spec.apply_overrides`).

    Raises:
        ConfigError: ``env`` names no negobs env, scenario or file (field ``env``), or a bad
            assignment (its full path).
    """
    if isinstance(env, ScenarioSpec):
        return NegObsEnv(scenario=env, overrides=overrides, render_mode=render_mode)
    if registered_negobs_env(env) is not None:
        return gym.make(env, overrides=overrides, render_mode=render_mode)
    if not (Path(env).is_file() or env in scenario_names()):
        ids = [i for i in gym.registry if i.startswith("negobs_gym/")]
        raise ConfigError(
            "env",
            f"unknown env {env!r}: not a registered id ({', '.join(ids)}), a shipped scenario "
            f"({', '.join(scenario_names())}) or an existing scenario TOML file",
        )
    return NegObsEnv(scenario=spec_for_env(env), overrides=overrides, render_mode=render_mode)
