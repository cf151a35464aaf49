"""Gymnasium environments of negobs_gym (registered ids in :mod:`negobs_gym.registration`).

One env class, :class:`NegObsEnv`, built from a scenario spec plus overrides
(:mod:`negobs_gym.spec`); the registered envs in :mod:`negobs_gym.envs.scenarios` name their
spec, and :func:`make_env` builds any of them from an id, a scene name, a TOML path or a spec.
Grid observation sources: :mod:`negobs_gym.envs.sources`.
"""

from negobs_gym.envs.base import NegObsEnv
from negobs_gym.envs.factory import GRID_SOURCE_NAMES, make_env, registered_negobs_env, source_overrides
from negobs_gym.envs.scenarios import (
    BrakingEnv,
    BrakingV0Env,
    OffroadNavEnv,
    OffroadNavV1Env,
    OffroadTrackEnv,
    PaperTStraightEnv,
    TrenchCrossingEnv,
)
from negobs_gym.envs.sources import GRID_SOURCES, DetectorSource, GridSource, OracleSource

__all__ = [
    "GRID_SOURCES",
    "GRID_SOURCE_NAMES",
    "BrakingEnv",
    "BrakingV0Env",
    "DetectorSource",
    "GridSource",
    "NegObsEnv",
    "OffroadNavEnv",
    "OffroadNavV1Env",
    "OffroadTrackEnv",
    "OracleSource",
    "PaperTStraightEnv",
    "TrenchCrossingEnv",
    "make_env",
    "registered_negobs_env",
    "source_overrides",
]
