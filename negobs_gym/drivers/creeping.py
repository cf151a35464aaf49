"""Stop and go, straight ahead: the driver that probes a filter's memory.

Full throttle up to a creep speed, then full brake to a standstill, a pause, and again. Behind
paper N's filter it edges ever closer to a pit it has been stopped for: at a standstill R(0) = B,
so every restart is allowed while the pit lies farther than the buffer, and a detector that loses
the pit's rim in the HDL-64's ring-free disc lets the next restart roll in (docs/safety.md,
"Hazard memory").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from negobs_gym.drivers.base import read_speed_mps
from negobs_gym.errors import require

#: Below this forward speed the car counts as stopped [m/s].
STOPPED_MPS = 0.05


@dataclass(frozen=True, kw_only=True)
class CreepingConfig:
    """Speed of each push and length of each pause."""

    target_speed_mps: float = 1.5  # the push's top speed, a walking pace [m/s]
    pause_steps: int = 10  # control steps stood still between pushes (1 s at 10 Hz)

    def __post_init__(self) -> None:
        require(
            np.isfinite(self.target_speed_mps) and self.target_speed_mps > 0,
            "target_speed_mps",
            "must be finite and > 0",
        )
        require(
            isinstance(self.pause_steps, int) and self.pause_steps >= 0, "pause_steps", "must be an int >= 0"
        )


class CreepingDriver:
    """Push (throttle 1) until ``target_speed_mps``, brake (-1) to a standstill, stand
    ``pause_steps`` steps, push again. Never steers."""

    def __init__(self, config: CreepingConfig | None = None) -> None:
        self.config = config or CreepingConfig()
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """Start with a push."""
        self._braking = False
        self._paused = 0

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """``[1, 0]`` pushing, ``[-1, 0]`` braking or pausing."""
        speed = read_speed_mps(info)
        if not self._braking and speed >= self.config.target_speed_mps:
            self._braking, self._paused = True, 0
        elif self._braking and speed < STOPPED_MPS:
            self._paused += 1
            if self._paused > self.config.pause_steps:
                self._braking = False
        return np.array([-1.0 if self._braking else 1.0, 0.0], dtype=np.float32)
