"""Eq. 18 of paper N: the braking (safety) distance and its inverse, the largest safe speed."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from negobs_gym.errors import ConfigError, require


@dataclass(frozen=True, kw_only=True)
class BrakingConfig:
    """Constants of R(v) = v^2 / (2 mu g) + v T_r + B (paper N, Eq. 18).

    The one place the package writes the paper's values: the filter, the envs and the demo read
    them from here.
    """

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


def _config(
    config: BrakingConfig | None,
    mu: float | None,
    reaction_time_s: float | None,
    buffer_m: float | None,
    g: float | None,
) -> BrakingConfig:
    """``config`` (default :class:`BrakingConfig`) with the given keyword overrides, validated."""
    base = config if config is not None else BrakingConfig()
    if not isinstance(base, BrakingConfig):
        raise ConfigError("config", f"must be a BrakingConfig, got {type(base).__name__}")
    overrides = {"mu": mu, "reaction_time_s": reaction_time_s, "buffer_m": buffer_m, "g_mps2": g}
    overrides = {k: v for k, v in overrides.items() if v is not None}
    return replace(base, **overrides) if overrides else base


def braking_distance_m(
    v_mps: ArrayLike,
    config: BrakingConfig | None = None,
    *,
    mu: float | None = None,
    reaction_time_s: float | None = None,
    buffer_m: float | None = None,
    g: float | None = None,
) -> np.ndarray:
    """Distance R(v) a vehicle at speed ``v_mps`` needs to stop, plus the buffer (Eq. 18).

    Constants come from ``config`` (default: the paper's, :class:`BrakingConfig`); a keyword
    overrides one of them. Negative speeds are treated by magnitude. Returns a float array shaped
    like ``v_mps``.
    """
    c = _config(config, mu, reaction_time_s, buffer_m, g)
    v = np.abs(np.asarray(v_mps, dtype=float))
    return v * v / (2.0 * c.mu * c.g_mps2) + v * c.reaction_time_s + c.buffer_m


def max_safe_speed_mps(
    d_m: ArrayLike,
    config: BrakingConfig | None = None,
    *,
    mu: float | None = None,
    reaction_time_s: float | None = None,
    buffer_m: float | None = None,
    g: float | None = None,
) -> np.ndarray:
    """Largest speed v with R(v) <= d (the inverse of Eq. 18); 0 when d < B, inf when d = inf."""
    c = _config(config, mu, reaction_time_s, buffer_m, g)
    d = np.asarray(d_m, dtype=float)
    a = 1.0 / (2.0 * c.mu * c.g_mps2)
    with np.errstate(invalid="ignore"):
        slack = np.maximum(d - c.buffer_m, 0.0)
        v = (-c.reaction_time_s + np.sqrt(c.reaction_time_s**2 + 4.0 * a * slack)) / (2.0 * a)
    return np.where(np.isposinf(d), np.inf, v)
