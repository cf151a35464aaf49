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
    r = np.array(ranges_m, dtype=np.float64, order="C")  # a copy whose flat view writes through
    index = np.asarray(ray_index)
    require_index(index, r.size)
    add_keyed_noise(r.reshape(-1), index.reshape(-1), config, key)
    return r


def require_index(index: np.ndarray, n: int) -> None:
    """Raise unless ``index`` holds ``n`` integer ray indices (one per range)."""
    if index.size != n or (n and not np.issubdtype(index.dtype, np.integer)):
        raise InterfaceError(
            f"ray_index: needs {n} integer ray indices, one per range, got {index.dtype} {index.shape}"
        )


def add_keyed_noise(
    ranges_m: np.ndarray, ray_index: np.ndarray, config: NoiseConfig, key: int, min_range_m: float = 0.0
) -> None:
    """:func:`apply_keyed_noise` in place on a writable 1-D float64 ``ranges_m`` (a scan's own
    buffer: no copy), after a range below ``min_range_m`` became NaN (the sensor's near limit).

    One compiled pass finds the hits and draws their uniforms; the Box-Muller normal is numpy's
    float32 ``log`` and ``cos`` (SIMD), which a compiled libm call can differ from in the last bit.
    """
    if not config.enabled or ranges_m.size == 0:
        if min_range_m > 0:
            ranges_m[ranges_m < min_range_m] = np.nan
        return
    hit, u1, u2, u3 = _hit_uniforms(ranges_m, ray_index, np.uint64(key), min_range_m)
    normal = np.log(u1, out=u1)  # sqrt(-2 log u1) cos(2 pi u2), each operation as numpy rounds it
    np.multiply(np.float32(-2.0), normal, out=normal)
    np.sqrt(normal, out=normal)
    angle = np.multiply(np.float32(2.0 * np.pi), u2, out=u2)
    np.multiply(normal, np.cos(angle, out=angle), out=normal)
    _add_noise(ranges_m, hit, normal, u3, np.float32(config.range_sigma_m), np.float32(config.dropout_prob))


@kernel
def _hit_uniforms(
    flat: np.ndarray, index: np.ndarray, key: np.uint64, min_range_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The positions of ``flat``'s hits (NaN below ``min_range_m``, set here; a miss stays NaN
    whatever its draw: draws for the hits only) and, per hit, three uniforms from the 64 random bits
    of ray ``index[hit]``, a counter-based draw that depends only on (key, index): SplitMix64 of the
    index xor the mixed key. 24 + 24 bits give (0, 1) uniforms for Box-Muller, 16 bits a [0, 1) one
    for the dropout. Every step is exact in float32, so this equals the numpy spelling bit for bit;
    the bits go through int32 (they fit) because int64 -> float32 does not vectorise."""
    n = flat.size
    hit = np.empty(n, dtype=np.int64)
    count = 0
    for k in range(n):
        if flat[k] < min_range_m:
            flat[k] = np.nan
        elif flat[k] == flat[k]:
            hit[count] = k
            count += 1
    seed = _splitmix64(key)
    u1 = np.empty(count, dtype=np.float32)
    u2 = np.empty(count, dtype=np.float32)
    u3 = np.empty(count, dtype=np.float32)
    scale = np.float32(1.0 / 2**24)
    for j in range(count):
        bits = _splitmix64(np.uint64(index[hit[j]]) ^ seed)
        u1[j] = (np.float32(np.int32(bits >> np.uint64(40))) + np.float32(0.5)) * scale
        mid = np.int32((bits >> np.uint64(16)) & np.uint64(0xFFFFFF))
        u2[j] = (np.float32(mid) + np.float32(0.5)) * scale
        u3[j] = np.float32(np.int32(bits & np.uint64(0xFFFF))) * np.float32(1.0 / 2**16)
    return hit[:count], u1, u2, u3


@kernel
def _add_noise(
    flat: np.ndarray, hit: np.ndarray, normal: np.ndarray, u3: np.ndarray, sigma: np.float32, drop: np.float32
) -> None:
    """In place: ``flat[hit] += sigma * normal`` (the product in float32, as numpy promotes a
    Python float with a float32 array), NaN where ``u3 < drop`` or the result is negative."""
    for j in range(hit.size):
        v = flat[hit[j]] + np.float64(sigma * normal[j])
        flat[hit[j]] = np.nan if (u3[j] < drop or v < 0) else v
