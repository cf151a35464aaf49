"""Cubic B-spline interpolation of a lattice at the points of a grid (the terrain's value noise).

``scipy.ndimage.map_coordinates(lattice, (rows, cols), order=3, mode="nearest")`` evaluated at
every (row, col) pair of two coordinate vectors, bit for bit, ~10x faster on a terrain-sized grid
(126 -> 12 ms for 2,119 x 657 samples; three octaves per terrain, so ~0.3 s of each new world).
The lattice is prefiltered by scipy exactly as ``map_coordinates`` does (padded 12 samples by its
edge, ``spline_filter``); the evaluation then computes each row's and each column's four weights
once instead of per point, and sums the 16 taps in scipy's order with its rounding
(``ni_interpolation.c``, ``ni_splines.c``). ``tests/sim/test_spline.py`` compares the two.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from negobs_gym.core.compiled import kernel
from negobs_gym.errors import GeometryError

__all__ = ["cubic_spline_grid"]

_PAD = 12  # samples scipy pads a "nearest" lattice with before its spline filter


def cubic_spline_grid(lattice: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(len(rows), len(cols)) cubic-spline values of ``lattice`` (2-D) at lattice coordinates
    ``rows`` x ``cols``, each within the lattice (``0 <= rows <= lattice.shape[0] - 1``, same for
    columns).

    Raises:
        GeometryError: ``lattice`` is not 2-D and finite, or a coordinate is not finite or lies
            outside the lattice.
    """
    lat = np.asarray(lattice, dtype=np.float64)
    r = np.ascontiguousarray(rows, dtype=np.float64).reshape(-1)
    c = np.ascontiguousarray(cols, dtype=np.float64).reshape(-1)
    if lat.ndim != 2 or lat.shape[0] < 1 or lat.shape[1] < 1 or not np.isfinite(lat).all():
        raise GeometryError(f"lattice must be a finite non-empty 2-D array, got shape {lat.shape}")
    for name, v, n in (("rows", r, lat.shape[0]), ("cols", c, lat.shape[1])):
        if not (np.isfinite(v).all() and (v >= 0.0).all() and (v <= n - 1).all()):
            raise GeometryError(f"{name} must be finite lattice coordinates in [0, {n - 1}]")
    padded = np.pad(lat, _PAD, mode="edge")
    coefficients = ndimage.spline_filter(padded, 3, output=np.float64, mode="nearest")
    return _spline_grid(coefficients, r, c, float(_PAD))


@kernel
def _cubic_weights(cc: float, w: np.ndarray) -> None:
    """The four cubic B-spline weights at coordinate ``cc``, as scipy rounds them."""
    x = cc - np.floor(cc)
    z = 1.0 - x
    w[1] = (x * x * (x - 2.0) * 3.0 + 4.0) / 6.0
    w[2] = (z * z * (z - 2.0) * 3.0 + 4.0) / 6.0
    w[0] = z * z * z / 6.0
    last = 1.0
    last -= w[0]
    last -= w[1]
    last -= w[2]
    w[3] = last


@kernel
def _spline_grid(coefficients: np.ndarray, rows: np.ndarray, cols: np.ndarray, pad: float) -> np.ndarray:
    ny, nx = rows.size, cols.size
    row_w, row_start = np.empty((ny, 4)), np.empty(ny, np.int64)
    col_w, col_start = np.empty((nx, 4)), np.empty(nx, np.int64)
    for j in range(ny):
        cc = rows[j] + pad
        row_start[j] = np.int64(np.floor(cc)) - 1
        _cubic_weights(cc, row_w[j])
    for i in range(nx):
        cc = cols[i] + pad
        col_start[i] = np.int64(np.floor(cc)) - 1
        _cubic_weights(cc, col_w[i])
    out = np.empty((ny, nx))
    for j in range(ny):
        r0 = row_start[j]
        for i in range(nx):
            c0 = col_start[i]
            t = 0.0
            for a in range(4):  # scipy's tap order: last axis fastest, weights multiplied in axis order
                for b in range(4):
                    coeff = coefficients[r0 + a, c0 + b]
                    coeff *= row_w[j, a]
                    coeff *= col_w[i, b]
                    t += coeff
            out[j, i] = t
    return out
