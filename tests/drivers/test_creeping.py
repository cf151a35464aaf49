"""The stop-and-go driver: push to the creep speed, brake to a standstill, pause, push again."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.drivers import CreepingConfig, CreepingDriver, make_driver
from negobs_gym.errors import ActionError, ConfigError


def _drive(driver: CreepingDriver, speeds: list[float]) -> list[float]:
    return [float(driver.act(None, {"speed_mps": v})[0]) for v in speeds]


def test_it_pushes_brakes_to_a_standstill_pauses_and_pushes_again() -> None:
    driver = CreepingDriver(CreepingConfig(target_speed_mps=1.5, pause_steps=2))
    speeds = [0.0, 0.8, 1.6, 1.0, 0.3, 0.0, 0.0, 0.0, 0.0]
    assert _drive(driver, speeds) == [1.0, 1.0, -1.0, -1.0, -1.0, -1.0, -1.0, 1.0, 1.0]
    action = driver.act(None, {"speed_mps": 0.5})
    assert action.dtype == np.float32 and action[1] == 0.0  # never steers
    driver.reset()
    assert _drive(driver, [2.0]) == [-1.0] and _drive(CreepingDriver(), [0.0]) == [1.0]


def test_it_is_named_and_checks_its_settings() -> None:
    driver = make_driver("creeping", terrain=None, target_speed_mps=1.0)  # reads no terrain
    assert isinstance(driver, CreepingDriver) and driver.config.target_speed_mps == 1.0
    with pytest.raises(ConfigError, match="pause_steps"):
        CreepingConfig(pause_steps=-1)
    with pytest.raises(ConfigError, match="target_speed_mps"):
        CreepingConfig(target_speed_mps=float("nan"))
    with pytest.raises(ActionError, match="speed_mps"):
        CreepingDriver().act(None, {"speed_mps": float("inf")})
