"""The scenario spec: the one description of an episode, as plain validated data.

A :class:`ScenarioSpec` holds the terrain (a preset or a course), its obstacles, the start, the
episode timing, the task, the reward weights and termination rules, the observation, INS noise,
physics, rendering, the default driver of a scripted run and its pass criteria. Every env,
campaign, training run and ``negobs`` command is built from a spec plus overrides
(``KEY.PATH=VALUE``, the commands' ``--set``). This package imports no env, evaluation, policy or
command-line code, so anything above it can read a spec.

- :mod:`~negobs_gym.spec.scenario` — :class:`ScenarioSpec` and its parts, TOML in and out;
- :mod:`~negobs_gym.spec.observation`, :mod:`~negobs_gym.spec.reward`,
  :mod:`~negobs_gym.spec.physics`, :mod:`~negobs_gym.spec.render` — the configs a spec holds;
- :mod:`~negobs_gym.spec.library` — the scenes shipped in ``negobs_gym/spec/scenes``, by name;
- :mod:`~negobs_gym.spec.overrides` — :func:`apply_overrides` and the spec behind an env id.
"""

from negobs_gym.spec.fields import Range
from negobs_gym.spec.library import load_scenario, scenario_names
from negobs_gym.spec.observation import (
    CHANNELS,
    POOLINGS,
    POSITIVE_DETECTORS,
    RIGS,
    ROUTE_MARGIN_M,
    SCAN_CLOCKS,
    ObservationConfig,
    PhantomConfig,
)
from negobs_gym.spec.overrides import (
    apply_overrides,
    combine_overrides,
    describe_overrides,
    env_with_overrides,
    recorded_env_in,
    spec_for_env,
)
from negobs_gym.spec.physics import EnvPhysicsConfig
from negobs_gym.spec.render import RenderConfig
from negobs_gym.spec.reward import RewardConfig
from negobs_gym.spec.scenario import (
    TERMINATION_RULES,
    CriteriaSpec,
    EpisodeSpec,
    InsSpec,
    NegativeObstacleEntry,
    PositiveObstacleEntry,
    RunSpec,
    SampledScenario,
    ScenarioSpec,
    StartSpec,
    TaskSpec,
    TerrainSpec,
    spec_from_toml,
    spec_to_toml,
)

__all__ = [
    "CHANNELS",
    "POOLINGS",
    "POSITIVE_DETECTORS",
    "RIGS",
    "ROUTE_MARGIN_M",
    "SCAN_CLOCKS",
    "TERMINATION_RULES",
    "CriteriaSpec",
    "EnvPhysicsConfig",
    "EpisodeSpec",
    "InsSpec",
    "NegativeObstacleEntry",
    "ObservationConfig",
    "PhantomConfig",
    "PositiveObstacleEntry",
    "Range",
    "RenderConfig",
    "RewardConfig",
    "RunSpec",
    "SampledScenario",
    "ScenarioSpec",
    "StartSpec",
    "TaskSpec",
    "TerrainSpec",
    "apply_overrides",
    "combine_overrides",
    "describe_overrides",
    "env_with_overrides",
    "load_scenario",
    "recorded_env_in",
    "scenario_names",
    "spec_for_env",
    "spec_from_toml",
    "spec_to_toml",
]
