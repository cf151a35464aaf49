"""The env's physics step (the scenario's ``physics.time_step_s``, 1/120 s) keeps braking physical."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from negobs_gym.envs.scenarios import BrakingV0Env
from negobs_gym.errors import ConfigError
from negobs_gym.spec import EnvPhysicsConfig, ScenarioSpec, load_scenario

MU, G = 0.65, 9.81  # paper N Eq. 18


def _full_brake_distance_m(substeps: int) -> tuple[float, float]:
    spec = load_scenario("braking_v0")
    obs = dataclasses.replace(spec.observation, source="oracle")
    spec = dataclasses.replace(
        spec, observation=obs, physics=dataclasses.replace(spec.physics, time_step_s=1 / (10 * substeps))
    )
    env = BrakingV0Env(scenario=spec)
    assert env._substeps == substeps
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
    # the flat-ground distance against v^2 / (2 mu g) is tests/sim/test_vehicle.py's; here the
    # env's rough braking track, 12 vs 24 sub-steps per 10 Hz control step
    d12, v12 = _full_brake_distance_m(12)
    d24, v24 = _full_brake_distance_m(24)
    assert v12 == pytest.approx(25 / 3.6, rel=0.05) and v24 == pytest.approx(25 / 3.6, rel=0.05)
    assert d12 == pytest.approx(d24, rel=0.05)
    assert d12 == pytest.approx(v12**2 / (2 * MU * G), rel=0.15)  # rough ground brakes a bit harder


def test_default_is_120_hz_and_bad_steps_are_rejected():
    assert EnvPhysicsConfig().time_step_s == pytest.approx(1 / 120)
    assert load_scenario("offroad_nav_v0").physics.time_step_s == pytest.approx(1 / 120)
    partial = ScenarioSpec.from_dict({**load_scenario("braking_v1").to_dict(), "physics": {"gui": False}})
    assert partial.physics.time_step_s == pytest.approx(1 / 120)  # a partial [physics] keeps 1/120 s
    for bad in (0.0, 1 / 2000, 0.1, float("nan")):
        with pytest.raises(ConfigError, match="time_step_s"):
            EnvPhysicsConfig(time_step_s=bad)
