"""Range realism: Gaussian range noise, random dropout, min/max range (docs/sensors.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.errors import InterfaceError, require


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
        raise InterfaceError("rng: noise is enabled, pass an np.random.Generator (or disable noise)")
    r = r + rng.normal(0.0, config.range_sigma_m, size=r.shape)
    r[rng.random(r.shape) < config.dropout_prob] = np.nan
    r[r < 0] = np.nan
    return r


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


@kernel
def _splitmix64(x: np.uint64) -> np.uint64:
    """SplitMix64 finaliser (Steele et al. 2014): a bijective 64-bit mix (arithmetic mod 2^64)."""
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


def apply_keyed_noise(
    ranges_m: np.ndarray, ray_index: np.ndarray, config: NoiseConfig, key: int
) -> np.ndarray:
    """Noisy copy of ``ranges_m`` whose draw for each ray depends only on ``(key, ray_index)``.

    Same model as :func:`apply_noise` (Gaussian range noise, dropout with ``dropout_prob``), but
    counter-based: a subset of a scan's rays (ROI casting) gets exactly the values the full scan
    gets for those rays, without drawing the others. One 64-bit hash per ray gives two 24-bit
    uniforms for a float32 Box-Muller normal and 16 bits for the dropout (probability resolution
    1/65536).
    """
    r = np.array(ranges_m, dtype=np.float64)
    if not config.enabled or r.size == 0:
        return r
    index = np.asarray(ray_index, dtype=np.int64).reshape(r.shape).reshape(-1)
    flat = r.reshape(-1)
    hit = np.flatnonzero(~np.isnan(flat))  # a miss stays NaN whatever its draw: draw for the hits only
    u1, u2, u3 = _uniforms(np.uint64(key), index, hit)
    # numpy's float32 log and cos (SIMD): a compiled libm call can differ in the last bit
    normal = np.sqrt(np.float32(-2.0) * np.log(u1)) * np.cos(np.float32(2.0 * np.pi) * u2)
    _add_noise(flat, hit, normal, u3, np.float32(config.range_sigma_m), np.float32(config.dropout_prob))
    return r


@kernel
def _uniforms(
    key: np.uint64, index: np.ndarray, hit: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per position in ``hit``, three uniforms from the 64 random bits of ray ``index[hit]``, a
    counter-based draw that depends only on (key, index): SplitMix64 of the index xor the mixed
    key. 24 + 24 bits give (0, 1) uniforms for Box-Muller, 16 bits a [0, 1) one for the dropout.
    Every step is exact in float32, so this equals the numpy spelling bit for bit; the bits go
    through int32 (they fit) because int64 -> float32 does not vectorise."""
    seed = _splitmix64(key)
    n = hit.size
    u1 = np.empty(n, dtype=np.float32)
    u2 = np.empty(n, dtype=np.float32)
    u3 = np.empty(n, dtype=np.float32)
    scale = np.float32(1.0 / 2**24)
    for j in range(n):
        bits = _splitmix64(np.uint64(index[hit[j]]) ^ seed)
        u1[j] = (np.float32(np.int32(bits >> np.uint64(40))) + np.float32(0.5)) * scale
        mid = np.int32((bits >> np.uint64(16)) & np.uint64(0xFFFFFF))
        u2[j] = (np.float32(mid) + np.float32(0.5)) * scale
        u3[j] = np.float32(np.int32(bits & np.uint64(0xFFFF))) * np.float32(1.0 / 2**16)
    return u1, u2, u3


@kernel
def _add_noise(
    flat: np.ndarray, hit: np.ndarray, normal: np.ndarray, u3: np.ndarray, sigma: np.float32, drop: np.float32
) -> None:
    """In place: ``flat[hit] += sigma * normal`` (the product in float32, as numpy promotes a
    Python float with a float32 array), NaN where ``u3 < drop`` or the result is negative."""
    for j in range(hit.size):
        v = flat[hit[j]] + np.float64(sigma * normal[j])
        flat[hit[j]] = np.nan if (u3[j] < drop or v < 0) else v
