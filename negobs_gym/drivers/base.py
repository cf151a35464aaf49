"""The scripted-driver protocol and the info keys drivers read.

Info keys read (the envs provide them in ``reset`` and ``step`` info):

* ``info["speed_mps"]``: forward speed [m/s] (all drivers).
* ``info["pose"]``: ``(x, y, z, roll, pitch, yaw)`` world pose of the rear-axle centre [m, rad]
  (pure pursuit; yaw = 0 faces world +Y, positive yaw turns left).

Actions follow :mod:`negobs_gym.safety.protocol`: ``[longitudinal, steering]`` in [-1, 1].
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from negobs_gym.errors import ActionError


@runtime_checkable
class Driver(Protocol):
    """A deterministic scripted policy."""

    def reset(self, seed: int | None = None) -> None:
        """Forget any episode state."""
        ...

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """The action ``[longitudinal, steering]`` for this step."""
        ...


def read_speed_mps(info: dict[str, Any]) -> float:
    """``info["speed_mps"]`` as a finite float, or a clear error."""
    if "speed_mps" not in info:
        raise ActionError("driver needs info['speed_mps'] (forward speed [m/s]) from the env")
    speed = float(info["speed_mps"])
    if not np.isfinite(speed):
        raise ActionError(f"info['speed_mps'] must be finite, got {speed}")
    return speed


def speed_command(speed_mps: float, target_mps: float, gain_per_mps: float) -> float:
    """Proportional longitudinal command towards ``target_mps``, clipped to [-1, 1]."""
    return float(np.clip(gain_per_mps * (target_mps - speed_mps), -1.0, 1.0))
