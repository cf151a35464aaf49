"""Range realism: Gaussian range noise, random dropout, min/max range (docs/sensors.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.errors import require


@dataclass(frozen=True, kw_only=True)
class NoiseConfig:
    """Range noise and dropout; ``enabled=False`` gives exact ranges.

    Attributes:
        enabled: Apply noise and dropout at all.
        range_sigma_m: Std of additive Gaussian range noise [m] (HDL-64E datasheet: < 2 cm).
        dropout_prob: Probability a return is lost.
    """

    enabled: bool = True
    range_sigma_m: float = 0.02  # HDL-64E S2 datasheet accuracy < 2 cm (1 sigma)
    dropout_prob: float = 0.01

    def __post_init__(self) -> None:
        require(
            math.isfinite(self.range_sigma_m) and self.range_sigma_m >= 0, "range_sigma_m", "must be >= 0"
        )
        require(0.0 <= self.dropout_prob < 1.0, "dropout_prob", "must be in [0, 1)")


def apply_noise(ranges_m: np.ndarray, config: NoiseConfig, rng: np.random.Generator | None) -> np.ndarray:
    """Noisy copy of ``ranges_m`` (NaN stays NaN); needs ``rng`` when noise is enabled."""
    r = np.array(ranges_m, dtype=np.float64)
    if not config.enabled:
        return r
    if not isinstance(rng, np.random.Generator):
        raise TypeError("noise is enabled: pass an np.random.Generator (or disable noise)")
    r = r + rng.normal(0.0, config.range_sigma_m, size=r.shape)
    r[rng.random(r.shape) < config.dropout_prob] = np.nan
    r[r < 0] = np.nan
    return r
