"""The ray-caster protocol shared by all backends."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.errors import ScanError


class RayCaster(Protocol):
    """Casts rays against a scene: ``cast(origins, directions, max_range_m) -> ranges`` (NaN = miss)."""

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_range_m: float) -> np.ndarray:
        """Ranges [m] of the first hit along each unit ray; NaN where nothing is hit within range."""
        ...


def check_rays(
    origins: np.ndarray, directions: np.ndarray, max_range_m: float, dtype: type = np.float64
) -> tuple[np.ndarray, np.ndarray]:
    """Validate ray arrays; returns float64 (N, 3) origins and unit directions as ``dtype``
    (float32 for a backend that casts in float32: d / |d| rounded once, as numpy would)."""
    o = np.asarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
        raise ScanError(f"origins and directions must both be (N, 3), got {o.shape} and {d.shape}")
    # one origin broadcast to every ray (a sensor's scan) is checked once
    if not np.isfinite(o[:1] if o.strides[0] == 0 else o).all():
        raise ScanError("origins and directions must be finite")
    if not (np.isfinite(max_range_m) and max_range_m > 0):
        raise ScanError(f"max_range_m must be finite and > 0, got {max_range_m}")
    unit = np.empty(d.shape, dtype=dtype)
    problem = _unit_rows(d, unit)
    if problem == _NOT_FINITE:
        raise ScanError("origins and directions must be finite")
    if problem == _ZERO:
        raise ScanError("directions must be non-zero")
    return o, unit


_NOT_FINITE, _ZERO = 1, 2


@kernel
def _unit_rows(d: np.ndarray, out: np.ndarray) -> int:
    """``out`` = d / |d| row by row, |d| = sqrt((x^2 + y^2) + z^2) as np.linalg.norm sums it.
    Returns 0, :data:`_NOT_FINITE` if any value is NaN/inf, else :data:`_ZERO` if some |d| < 1e-12."""
    problem = 0
    for k in range(d.shape[0]):
        x, y, z = d[k, 0], d[k, 1], d[k, 2]
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            return _NOT_FINITE
        n = np.sqrt(x * x + y * y + z * z)
        if n < 1e-12:
            problem = _ZERO
        out[k, 0], out[k, 1], out[k, 2] = x / n, y / n, z / n
    return problem
