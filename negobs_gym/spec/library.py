"""The scenario library: TOML specs shipped in ``negobs_gym/spec/scenes``, loadable by name."""

from __future__ import annotations

import dataclasses
from importlib import resources
from pathlib import Path

from negobs_gym.errors import ConfigError
from negobs_gym.spec.scenario import ScenarioSpec, spec_from_toml

__all__ = ["load_scenario", "scenario_names"]

_SCENES = "scenes"


def _scenes():
    return resources.files("negobs_gym.spec").joinpath(_SCENES)


def scenario_names() -> tuple[str, ...]:
    """Names of the shipped scenarios (file names without ``.toml``), sorted."""
    return tuple(sorted(p.name[: -len(".toml")] for p in _scenes().iterdir() if p.name.endswith(".toml")))


def load_scenario(name_or_path: str | Path) -> ScenarioSpec:
    """A shipped scenario by name (``"paper_n_three_pits"``), or a spec from a TOML file path.

    A file's relative ``run.policy`` path is read from the file's folder where a model lies there
    (a suite of specs beside its models runs from any directory), else as given: a shipped policy's
    name, or a path from the working directory.

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
        return _policy_beside(spec_from_toml(path.read_text(encoding="utf-8")), path.parent)
    resource = _scenes().joinpath(f"{text}.toml")
    if not resource.is_file():
        raise ConfigError("scenario", f"unknown scenario {text!r}; shipped: {', '.join(scenario_names())}")
    return spec_from_toml(resource.read_text(encoding="utf-8"))


def _policy_beside(spec: ScenarioSpec, folder: Path) -> ScenarioSpec:
    """``spec`` with ``run.policy`` joined to ``folder`` when a saved model lies there."""
    policy = spec.run.policy
    if not policy or Path(policy).is_absolute():
        return spec
    beside = folder / policy
    if not (beside.is_file() or Path(f"{beside}.zip").is_file()):
        return spec
    return dataclasses.replace(spec, run=dataclasses.replace(spec.run, policy=str(beside)))
