"""Drive straight at a constant target speed (P-controller on ``info["speed_mps"]``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from negobs_gym.drivers.base import read_speed_mps, speed_command
from negobs_gym.errors import require


@dataclass(frozen=True, kw_only=True)
class ConstantSpeedConfig:
    """Target speed and gain of the constant-speed driver."""

    target_speed_mps: float = 25.0 / 3.6  # paper N's test speed, 25 km/h (Sec. 4) [m/s]
    gain_per_mps: float = 0.5  # longitudinal command per m/s of speed error [1/(m/s)]

    def __post_init__(self) -> None:
        require(
            np.isfinite(self.target_speed_mps) and self.target_speed_mps >= 0,
            "target_speed_mps",
            "must be finite and >= 0",
        )
        require(
            np.isfinite(self.gain_per_mps) and self.gain_per_mps > 0, "gain_per_mps", "must be finite and > 0"
        )


class ConstantSpeedDriver:
    """Straight ahead (steering 0) at ``target_speed_mps``."""

    def __init__(self, config: ConstantSpeedConfig | None = None) -> None:
        self.config = config or ConstantSpeedConfig()

    def reset(self, seed: int | None = None) -> None:
        """Stateless; nothing to reset."""

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """``[P(target - speed), 0]``."""
        cmd = speed_command(read_speed_mps(info), self.config.target_speed_mps, self.config.gain_per_mps)
        return np.array([cmd, 0.0], dtype=np.float32)
