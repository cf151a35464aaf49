"""The env's physics sub-step count (EnvConfig.physics_substeps) keeps braking physical."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.envs.config import EnvConfig
from negobs_gym.errors import ConfigError

MU, G = 0.65, 9.81  # paper N Eq. 18


def _full_brake_distance_m(substeps: int) -> tuple[float, float]:
    probe = gym.make("negobs_gym/Braking-v0")
    cfg = probe.unwrapped.default_config()
    probe.close()
    obs = dataclasses.replace(cfg.observation, source="oracle")
    env = gym.make(
        "negobs_gym/Braking-v0", config=dataclasses.replace(cfg, observation=obs, physics_substeps=substeps)
    )
    _, info = env.reset(seed=3)
    v0 = info["speed_mps"]
    start = info["pose"][:2]
    for _ in range(60):
        _, _, term, trunc, info = env.step(np.array([-1.0, 0.0], np.float32))
        if info["speed_mps"] < 0.01 or term or trunc:
            break
    env.close()
    return float(np.linalg.norm(info["pose"][:2] - start)), v0


def test_full_brake_in_the_env_at_120_hz_matches_240_hz_within_5_percent():
    # the flat-ground distance against v^2 / (2 mu g) at both rates is tests/sim/test_vehicle.py's;
    # here the env's rough braking track, 12 vs 24 sub-steps per 10 Hz control step
    d12, v12 = _full_brake_distance_m(12)
    d24, v24 = _full_brake_distance_m(24)
    assert v12 == pytest.approx(25 / 3.6, rel=0.05) and v24 == pytest.approx(25 / 3.6, rel=0.05)
    assert d12 == pytest.approx(d24, rel=0.05)
    assert d12 == pytest.approx(v12**2 / (2 * MU * G), rel=0.15)  # rough ground brakes a bit harder


def test_default_is_120_hz_and_bad_counts_are_rejected():
    cfg = EnvConfig()
    assert cfg.physics_substeps == 12 and math.isclose(cfg.physics_time_step_s, 1 / 120)
    for bad in (0, 2, 200, 1.5):
        with pytest.raises(ConfigError, match="physics_substeps"):
            EnvConfig(physics_substeps=bad)
