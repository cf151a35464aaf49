"""Scenario envs: small subclasses of NegObsEnv that pick a terrain preset and a config."""

from __future__ import annotations

import dataclasses

import numpy as np

from negobs_gym.envs.base import NegObsEnv
from negobs_gym.envs.config import EnvConfig
from negobs_gym.sim import presets
from negobs_gym.sim.types import Terrain

__all__ = ["BrakingEnv", "OffroadNavEnv", "PaperTStraightEnv", "TrenchCrossingEnv"]

BRAKING_SPEED_MPS = 25.0 / 3.6  # paper N §4: 25 km/h


def _seed(rng: np.random.Generator) -> int:
    return int(rng.integers(0, 2**31 - 1))


class BrakingEnv(NegObsEnv):
    """Straight track, a 1.0 m x 3.0 m x 0.8 m ditch 20-40 m ahead, start at 25 km/h.

    See :class:`~negobs_gym.envs.base.NegObsEnv` for spaces, rewards and info. The ditch spans both
    wheel tracks; stopping before it (or reaching the far end) is the task.
    """

    ditch_distance_range_m = (20.0, 40.0)

    @classmethod
    def default_config(cls) -> EnvConfig:
        return EnvConfig(start_speed_mps=BRAKING_SPEED_MPS, time_limit_s=15.0)

    def _make_terrain(self, rng: np.random.Generator) -> Terrain:
        lo, hi = self.ditch_distance_range_m
        return presets.braking_track(ditch_distance_m=float(rng.uniform(lo, hi)), seed=_seed(rng))


class OffroadNavEnv(NegObsEnv):
    """Reach the goal along a winding course with negative and positive obstacles."""

    @classmethod
    def default_config(cls) -> EnvConfig:
        return dataclasses.replace(EnvConfig(), time_limit_s=60.0)

    def _make_terrain(self, rng: np.random.Generator) -> Terrain:
        return presets.winding_course(seed=_seed(rng), length_m=120.0)


class TrenchCrossingEnv(NegObsEnv):
    """A 3 m wide, 1 m deep trench across the track 30 m ahead: too wide to cross, stop before it."""

    def _make_terrain(self, rng: np.random.Generator) -> Terrain:
        return presets.trench_crossing(seed=_seed(rng))


class PaperTStraightEnv(NegObsEnv):
    """Paper T's straight track between two earth banks; drive to the end."""

    def _make_terrain(self, rng: np.random.Generator) -> Terrain:
        return presets.straight_banked_track(seed=_seed(rng))
