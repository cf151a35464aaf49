"""Deprecated: the scenario spec moved to :mod:`negobs_gym.spec`, scenario runs to :mod:`negobs_gym.eval`.

``from negobs_gym.scenarios import X`` keeps working for one release and warns once per name
with the new place; nothing in the package imports this module.
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any

#: Old name -> module that holds it now.
MOVED: dict[str, str] = {
    **dict.fromkeys(
        (
            "Range",
            "ScenarioSpec",
            "apply_overrides",
            "combine_overrides",
            "describe_overrides",
            "env_with_overrides",
            "load_scenario",
            "scenario_names",
            "spec_for_env",
            "spec_from_toml",
            "spec_to_toml",
        ),
        "negobs_gym.spec",
    ),
    **dict.fromkeys(
        ("ScenarioResult", "run_scenario", "run_scenario_seeds"), "negobs_gym.eval.scenario_runner"
    ),
}

__all__ = sorted(MOVED)


def __getattr__(name: str) -> Any:
    if name not in MOVED:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    warnings.warn(
        f"negobs_gym.scenarios.{name} moved to {MOVED[name]}.{name}; import it from there",
        DeprecationWarning,
        stacklevel=2,
    )
    value = getattr(importlib.import_module(MOVED[name]), name)
    globals()[name] = value  # warn once per name
    return value
