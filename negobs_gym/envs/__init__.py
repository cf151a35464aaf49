"""Gymnasium environments of negobs_gym (registered ids in :mod:`negobs_gym.registration`)."""

from negobs_gym.envs.base import NegObsEnv
from negobs_gym.envs.config import CHANNELS, EnvConfig, ObservationConfig, RewardConfig
from negobs_gym.envs.scenarios import BrakingEnv, OffroadNavEnv, PaperTStraightEnv, TrenchCrossingEnv

__all__ = [
    "CHANNELS",
    "BrakingEnv",
    "EnvConfig",
    "NegObsEnv",
    "ObservationConfig",
    "OffroadNavEnv",
    "PaperTStraightEnv",
    "RewardConfig",
    "TrenchCrossingEnv",
]
