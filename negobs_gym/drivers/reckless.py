"""Full throttle up to 25 km/h, then hold that speed; never brakes, never steers."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from negobs_gym.drivers.base import read_speed_mps
from negobs_gym.errors import require


@dataclass(frozen=True, kw_only=True)
class RecklessConfig:
    """Speed the reckless driver accelerates to."""

    target_speed_mps: float = 25.0 / 3.6  # 25 km/h, paper N's experiment speed [m/s]

    def __post_init__(self) -> None:
        require(
            np.isfinite(self.target_speed_mps) and self.target_speed_mps > 0,
            "target_speed_mps",
            "must be finite and > 0",
        )


class RecklessDriver:
    """Throttle 1 below the target speed, 0 (coast/hold) at or above it. Never negative."""

    def __init__(self, config: RecklessConfig | None = None) -> None:
        self.config = config or RecklessConfig()

    def reset(self, seed: int | None = None) -> None:
        """Stateless; nothing to reset."""

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """``[1, 0]`` below the target speed, else ``[0, 0]``."""
        cmd = 1.0 if read_speed_mps(info) < self.config.target_speed_mps else 0.0
        return np.array([cmd, 0.0], dtype=np.float32)
