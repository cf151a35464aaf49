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
    raise_ray_problem(_unit_rows(d, unit))
    return o, unit


def raise_ray_problem(problem: int) -> None:
    """Raise the :class:`ScanError` of a ray kernel's problem code (0: none)."""
    if problem == _NOT_FINITE:
        raise ScanError("origins and directions must be finite")
    if problem == _ZERO:
        raise ScanError("directions must be non-zero")


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


@kernel
def rotated_unit_rows(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    index: np.ndarray,
    use_index: bool,
    r: np.ndarray,
    out: np.ndarray,
) -> int:
    """``out`` (n, 3) = the rows ``index`` (all: ``use_index`` False) of the directions with
    coordinate planes ``x, y, z`` rotated by ``r`` (coordinate i ``(x R[i,0] + y R[i,1]) + z
    R[i,2]``, as ``sensors.lidar.rotate_planes`` computes it), then made unit as :func:`check_rays`
    makes them, in one pass. Returns :func:`_unit_rows`'s problem code."""
    problem = 0
    for k in range(out.shape[0]):
        m = index[k] if use_index else k
        xm, ym, zm = x[m], y[m], z[m]
        a = xm * r[0, 0] + ym * r[0, 1] + zm * r[0, 2]
        b = xm * r[1, 0] + ym * r[1, 1] + zm * r[1, 2]
        c = xm * r[2, 0] + ym * r[2, 1] + zm * r[2, 2]
        if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(c)):
            return _NOT_FINITE
        n = np.sqrt(a * a + b * b + c * c)
        if n < 1e-12:
            problem = _ZERO
        out[k, 0], out[k, 1], out[k, 2] = a / n, b / n, c / n
    return problem
