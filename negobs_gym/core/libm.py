"""Transcendental functions from the C library, element by element, the same on every x86-64 CPU.

numpy picks its routine for some functions by the CPU it runs on: on an AVX-512 CPU float64
``arctan2``, ``exp``, ``log2``, ``arcsin``, ``arctan`` and ``tan`` run SIMD routines
(SVML) that differ from the C library's, which an AVX2 CPU runs, in the last bit for 1-10 % of
inputs. These kernels call the C library's function for every element (numba lowers ``math``
functions to libm calls), so a result depends on the C library only, not on the CPU.
docs/determinism.md lists the other machine-dependent paths and how they are pinned.

Arrays of any shape are accepted (float64); the result has the input's shape. Python floats
need none of this: ``math`` calls the C library already.
"""

from __future__ import annotations

import math

import numpy as np

from negobs_gym.core.compiled import kernel


@kernel
def _exp(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = math.exp(x[i])
    return out


@kernel
def _log2(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = math.log2(x[i])
    return out


@kernel
def _tan(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = math.tan(x[i])
    return out


@kernel
def _arctan(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = math.atan(x[i])
    return out


@kernel
def _arcsin(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    for i in range(x.size):
        v = x[i]
        out[i] = math.asin(v) if -1.0 <= v <= 1.0 else np.nan  # numpy's domain rule, no exception
    return out


@kernel
def _arctan2(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    out = np.empty_like(y)
    for i in range(y.size):
        out[i] = math.atan2(y[i], x[i])
    return out


def _unary(fn, x: np.ndarray | float) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    return fn(np.ascontiguousarray(a).reshape(-1)).reshape(a.shape)


def exp(x: np.ndarray | float) -> np.ndarray:
    """``e**x`` (float64), the C library's ``exp``."""
    return _unary(_exp, x)


def log2(x: np.ndarray | float) -> np.ndarray:
    """Base-2 logarithm (float64), the C library's ``log2``."""
    return _unary(_log2, x)


def tan(x: np.ndarray | float) -> np.ndarray:
    """Tangent (float64), the C library's ``tan``."""
    return _unary(_tan, x)


def arctan(x: np.ndarray | float) -> np.ndarray:
    """Arc tangent (float64), the C library's ``atan``."""
    return _unary(_arctan, x)


def arcsin(x: np.ndarray | float) -> np.ndarray:
    """Arc sine (float64), the C library's ``asin``; NaN outside [-1, 1] as in numpy."""
    return _unary(_arcsin, x)


def arctan2(y: np.ndarray | float, x: np.ndarray | float) -> np.ndarray:
    """Angle of (x, y) (float64, broadcast), the C library's ``atan2``."""
    yb, xb = np.broadcast_arrays(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))
    flat = _arctan2(np.ascontiguousarray(yb).reshape(-1), np.ascontiguousarray(xb).reshape(-1))
    return flat.reshape(yb.shape)
