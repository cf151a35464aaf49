"""Gymnasium registration of the negobs_gym environments.

``import negobs_gym`` must register the envs, yet ``import negobs_gym.detector`` must not import
gymnasium (the detector runs on recorded scans, without a simulator or RL stack). So the package
registers at once when gymnasium is already imported, and otherwise installs a one-shot import
hook that registers right after gymnasium finishes importing. Registration is idempotent.

Names follow Gymnasium's promise: a version bump is a new version of the same task (``-v1``
replaces ``-v0``, and ``gymnasium.make`` of ``-v0`` warns that it is out of date), while a different
task has its own name. OffroadNav (drive the course, reach the goal; leaving the track is allowed)
and OffroadTrack (the same course, and leaving the track ends the episode) are two tasks. An old id
of a renamed task stays as an alias (:data:`ALIASES`) that builds the same env and warns once.
"""

from __future__ import annotations

import dataclasses
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

#: (id, entry point, max_episode_steps); entry points are strings, so nothing heavy is imported.
#: No ``TimeLimit`` from the registry (None): each env truncates at its spec's ``time_limit_s``,
#: so the limit is the same whether an env is made here or built directly, and a ``config`` passed
#: to ``gymnasium.make`` changes it.
ENV_SPECS: tuple[tuple[str, str, int | None], ...] = (
    ("negobs_gym/OffroadNav-v0", "negobs_gym.envs.scenarios:OffroadNavEnv", None),
    ("negobs_gym/OffroadNav-v1", "negobs_gym.envs.scenarios:OffroadNavV1Env", None),
    ("negobs_gym/OffroadTrack-v0", "negobs_gym.envs.scenarios:OffroadTrackEnv", None),
    ("negobs_gym/Braking-v0", "negobs_gym.envs.scenarios:BrakingV0Env", None),
    ("negobs_gym/Braking-v1", "negobs_gym.envs.scenarios:BrakingEnv", None),
    ("negobs_gym/TrenchCrossing-v0", "negobs_gym.envs.scenarios:TrenchCrossingEnv", None),
    ("negobs_gym/PaperTStraight-v0", "negobs_gym.envs.scenarios:PaperTStraightEnv", None),
)

#: Old ids of renamed tasks, kept for one release: (old id, new id, entry point). The entry point is
#: the new id's env class under a subclass that calls :func:`warn_alias` (so ``make_env`` and
#: ``registered_negobs_env`` see a negobs env, as for the new id).
ALIASES: tuple[tuple[str, str, str], ...] = (
    (
        "negobs_gym/OffroadNav-v2",
        "negobs_gym/OffroadTrack-v0",
        "negobs_gym.envs.aliases:OffroadNavV2Alias",
    ),
)

#: The shipped scene (``negobs_gym/spec/scenes/NAME.toml``) each id (and alias) runs: plain data,
#: so the spec layer finds an id's scenario without importing the envs.
SCENES: dict[str, str] = {
    "negobs_gym/OffroadNav-v0": "offroad_nav_v0",
    "negobs_gym/OffroadNav-v1": "offroad_nav_v1",
    "negobs_gym/OffroadTrack-v0": "offroad_nav_v2",
    "negobs_gym/OffroadNav-v2": "offroad_nav_v2",  # alias of OffroadTrack-v0
    "negobs_gym/Braking-v0": "braking_v0",
    "negobs_gym/Braking-v1": "braking_v1",
    "negobs_gym/TrenchCrossing-v0": "trench_crossing_v0",
    "negobs_gym/PaperTStraight-v0": "paper_t_straight_v0",
}


#: The aliases that have warned in this process (each warns once).
_WARNED: set[str] = set()


def register_envs() -> None:
    """Register every negobs_gym env id and alias with gymnasium; safe to call any number of times."""
    import gymnasium

    for env_id, entry_point, max_steps in ENV_SPECS:
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point, max_episode_steps=max_steps)
    for old_id, new_id, entry_point in ALIASES:
        # Not gymnasium.register(old_id): gymnasium.make warns "out of date, upgrade to vN" for
        # any id whose name has a higher version registered (it compares the registry's specs by
        # their parsed name), so a spec named OffroadNav-v2 would make every OffroadNav-v1 look
        # out of date, although v1 is the current version of its task. The alias is a registry
        # key holding the new id's spec (its id, name and version are the new id's), with the
        # warning entry point: make finds it by key, the version check never sees a v2.
        if old_id not in gymnasium.registry:
            gymnasium.registry[old_id] = dataclasses.replace(gymnasium.spec(new_id), entry_point=entry_point)


def warn_alias(old_id: str) -> None:
    """Warn (a ``DeprecationWarning``, once per process) that ``old_id`` is now its new id."""
    if old_id in _WARNED:
        return
    _WARNED.add(old_id)
    new_id = next(new for old, new, _ in ALIASES if old == old_id)
    # stacklevel: this function, the alias env's __init__, gymnasium.make, then the caller
    warnings.warn(
        f"{old_id} is now {new_id}, the same env (a task of its own, not a new version of "
        f"{old_id.rsplit('-v', 1)[0]}); the old id goes in a later release",
        DeprecationWarning,
        stacklevel=4,
    )


class _RegisterAfterGymnasiumImport(importlib.abc.MetaPathFinder):
    """Meta-path finder that wraps gymnasium's loader to call :func:`register_envs` afterwards."""

    def find_spec(self, fullname, path, target=None):
        if fullname != "gymnasium":
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        original_exec = loader.exec_module

        def exec_module(module: ModuleType) -> None:
            original_exec(module)
            register_envs()

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def register_now_or_on_gymnasium_import() -> None:
    """Register the envs now if gymnasium is loaded, else as soon as it is imported."""
    if "gymnasium" in sys.modules:
        register_envs()
    elif not any(isinstance(f, _RegisterAfterGymnasiumImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterAfterGymnasiumImport())
