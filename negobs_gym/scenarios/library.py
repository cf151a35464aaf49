"""The scenario library: TOML specs shipped in ``negobs_gym/scenarios/scenes``, loadable by name."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from negobs_gym.errors import ConfigError
from negobs_gym.scenarios.spec import ScenarioSpec, spec_from_toml

__all__ = ["load_scenario", "scenario_names"]

_SCENES = "scenes"


def _scenes():
    return resources.files("negobs_gym.scenarios").joinpath(_SCENES)


def scenario_names() -> tuple[str, ...]:
    """Names of the shipped scenarios (file names without ``.toml``), sorted."""
    return tuple(sorted(p.name[: -len(".toml")] for p in _scenes().iterdir() if p.name.endswith(".toml")))


def load_scenario(name_or_path: str | Path) -> ScenarioSpec:
    """A shipped scenario by name (``"paper_n_three_pits"``), or a spec from a TOML file path.

    Raises:
        ConfigError: no such scenario or file (field ``scenario``), or an invalid spec (its field).
    """
    if isinstance(name_or_path, ScenarioSpec):
        return name_or_path
    text = str(name_or_path)
    if text.endswith(".toml") or Path(text).is_file():
        path = Path(text)
        if not path.is_file():
            raise ConfigError("scenario", f"no such file: {path}")
        return spec_from_toml(path.read_text(encoding="utf-8"))
    resource = _scenes().joinpath(f"{text}.toml")
    if not resource.is_file():
        raise ConfigError("scenario", f"unknown scenario {text!r}; shipped: {', '.join(scenario_names())}")
    return spec_from_toml(resource.read_text(encoding="utf-8"))
