"""Gymnasium registration of the negobs_gym environments.

``import negobs_gym`` must register the envs, yet ``import negobs_gym.detector`` must not import
gymnasium (the detector runs on recorded scans, without a simulator or RL stack). So the package
registers at once when gymnasium is already imported, and otherwise installs a one-shot import
hook that registers right after gymnasium finishes importing. Registration is idempotent.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from types import ModuleType

#: (id, entry point, max_episode_steps); entry points are strings, so nothing heavy is imported.
#: No ``TimeLimit`` from the registry (None): each env truncates at its spec's ``time_limit_s``,
#: so the limit is the same whether an env is made here or built directly, and a ``config`` passed
#: to ``gymnasium.make`` changes it.
ENV_SPECS: tuple[tuple[str, str, int | None], ...] = (
    ("negobs_gym/OffroadNav-v0", "negobs_gym.envs.scenarios:OffroadNavEnv", None),
    ("negobs_gym/OffroadNav-v1", "negobs_gym.envs.scenarios:OffroadNavV1Env", None),
    ("negobs_gym/OffroadNav-v2", "negobs_gym.envs.scenarios:OffroadNavV2Env", None),
    ("negobs_gym/Braking-v0", "negobs_gym.envs.scenarios:BrakingV0Env", None),
    ("negobs_gym/Braking-v1", "negobs_gym.envs.scenarios:BrakingEnv", None),
    ("negobs_gym/TrenchCrossing-v0", "negobs_gym.envs.scenarios:TrenchCrossingEnv", None),
    ("negobs_gym/PaperTStraight-v0", "negobs_gym.envs.scenarios:PaperTStraightEnv", None),
)

#: The shipped scene (``negobs_gym/spec/scenes/NAME.toml``) each id runs: plain data, so the spec
#: layer finds an id's scenario without importing the envs.
SCENES: dict[str, str] = {
    "negobs_gym/OffroadNav-v0": "offroad_nav_v0",
    "negobs_gym/OffroadNav-v1": "offroad_nav_v1",
    "negobs_gym/OffroadNav-v2": "offroad_nav_v2",
    "negobs_gym/Braking-v0": "braking_v0",
    "negobs_gym/Braking-v1": "braking_v1",
    "negobs_gym/TrenchCrossing-v0": "trench_crossing_v0",
    "negobs_gym/PaperTStraight-v0": "paper_t_straight_v0",
}


def register_envs() -> None:
    """Register every negobs_gym env id with gymnasium; safe to call any number of times."""
    import gymnasium

    for env_id, entry_point, max_steps in ENV_SPECS:
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point, max_episode_steps=max_steps)


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
