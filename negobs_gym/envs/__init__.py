"""Gymnasium environments of negobs_gym (registered ids in :mod:`negobs_gym.registration`).

One env class, :class:`NegObsEnv`, driven by a scenario spec (:mod:`negobs_gym.scenarios`); the
registered envs in :mod:`negobs_gym.envs.scenarios` name their spec. Grid observation sources:
:mod:`negobs_gym.envs.sources`.
"""

from negobs_gym.envs.base import NegObsEnv, registered_negobs_env
from negobs_gym.envs.config import CHANNELS, EnvConfig, ObservationConfig, RewardConfig
from negobs_gym.envs.scenarios import (
    BrakingEnv,
    BrakingV0Env,
    OffroadNavEnv,
    PaperTStraightEnv,
    TrenchCrossingEnv,
)
from negobs_gym.envs.sources import GRID_SOURCES, DetectorSource, GridSource, OracleSource

__all__ = [
    "CHANNELS",
    "GRID_SOURCES",
    "BrakingEnv",
    "BrakingV0Env",
    "DetectorSource",
    "EnvConfig",
    "GridSource",
    "NegObsEnv",
    "ObservationConfig",
    "OffroadNavEnv",
    "OracleSource",
    "PaperTStraightEnv",
    "RewardConfig",
    "TrenchCrossingEnv",
    "registered_negobs_env",
]
