"""Eq. 18 of paper N: the braking (safety) distance and its inverse, the largest safe speed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from negobs_gym.errors import require


@dataclass(frozen=True, kw_only=True)
class BrakingConfig:
    """Constants of R(v) = v^2 / (2 mu g) + v T_r + B (paper N, Eq. 18)."""

    mu: float = 0.65  # tyre-ground friction coefficient, Eq. 18 [-]
    reaction_time_s: float = 0.25  # reaction time T_r, Eq. 18 [s]
    buffer_m: float = 5.0  # front overhang + safety buffer B, Eq. 18 [m]
    g_mps2: float = 9.81  # gravity, Eq. 18 [m/s^2]

    def __post_init__(self) -> None:
        for name in ("mu", "g_mps2"):
            value = getattr(self, name)
            require(np.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value!r}")
        for name in ("reaction_time_s", "buffer_m"):
            value = getattr(self, name)
            require(np.isfinite(value) and value >= 0, name, f"must be finite and >= 0, got {value!r}")


def braking_distance_m(
    v_mps: ArrayLike,
    mu: float = 0.65,
    reaction_time_s: float = 0.25,
    buffer_m: float = 5.0,
    g: float = 9.81,
) -> np.ndarray:
    """Distance R(v) a vehicle at speed ``v_mps`` needs to stop, plus the buffer (Eq. 18).

    Negative speeds are treated by magnitude. Returns a float array shaped like ``v_mps``.
    """
    BrakingConfig(mu=mu, reaction_time_s=reaction_time_s, buffer_m=buffer_m, g_mps2=g)
    v = np.abs(np.asarray(v_mps, dtype=float))
    return v * v / (2.0 * mu * g) + v * reaction_time_s + buffer_m


def max_safe_speed_mps(
    d_m: ArrayLike,
    mu: float = 0.65,
    reaction_time_s: float = 0.25,
    buffer_m: float = 5.0,
    g: float = 9.81,
) -> np.ndarray:
    """Largest speed v with R(v) <= d (the inverse of Eq. 18); 0 when d < B, inf when d = inf."""
    BrakingConfig(mu=mu, reaction_time_s=reaction_time_s, buffer_m=buffer_m, g_mps2=g)
    d = np.asarray(d_m, dtype=float)
    a = 1.0 / (2.0 * mu * g)
    with np.errstate(invalid="ignore"):
        slack = np.maximum(d - buffer_m, 0.0)
        v = (-reaction_time_s + np.sqrt(reaction_time_s**2 + 4.0 * a * slack)) / (2.0 * a)
    return np.where(np.isposinf(d), np.inf, v)
