"""Scenarios as data: TOML/dict scenario specs, the shipped paper scenes, and scripted scenario runs.

- :mod:`negobs_gym.scenarios.spec` — :class:`ScenarioSpec`, loaded from TOML or a dict, validated
  field by field, with ranges drawn from the env's generator at each reset;
- :mod:`negobs_gym.scenarios.library` — the TOML scenes shipped in ``negobs_gym/scenarios/scenes``
  (paper N and paper T scenes and the registered envs), loadable by name;
- :mod:`negobs_gym.scenarios.runner` — :func:`run_scenario`: one scripted episode, a frozen
  :class:`ScenarioResult` to assert on, and the spec's pass criteria; :func:`run_scenario_seeds`
  runs it per seed in several processes;
- :mod:`negobs_gym.scenarios.overrides` — :func:`apply_overrides`: single settings changed by
  ``KEY.PATH=VALUE`` (the commands' ``--set``), the spec behind an env id, and the changed
  scenario written beside a run's results.
"""

from negobs_gym.scenarios.fields import Range
from negobs_gym.scenarios.library import load_scenario, scenario_names
from negobs_gym.scenarios.overrides import (
    apply_overrides,
    combine_overrides,
    describe_overrides,
    env_with_overrides,
    spec_for_env,
)
from negobs_gym.scenarios.runner import ScenarioResult, run_scenario, run_scenario_seeds
from negobs_gym.scenarios.spec import ScenarioSpec, spec_from_toml, spec_to_toml

__all__ = [
    "Range",
    "ScenarioResult",
    "ScenarioSpec",
    "apply_overrides",
    "combine_overrides",
    "describe_overrides",
    "env_with_overrides",
    "load_scenario",
    "run_scenario",
    "run_scenario_seeds",
    "scenario_names",
    "spec_for_env",
    "spec_from_toml",
    "spec_to_toml",
]
