"""Transcendental functions from the C library, element by element, the same on every x86-64 CPU.

numpy picks its routine for some functions by the CPU it runs on: on an AVX-512 CPU float64
``arctan2``, ``exp``, ``log2``, ``arcsin``, ``arctan`` and ``tan`` run SIMD routines
(SVML) that differ from the C library's, which an AVX2 CPU runs, in the last bit for 1-10 % of
inputs. These kernels call the C library's function for every element (numba lowers ``math``
functions to libm calls), so a result depends on the C library only, not on the CPU.
docs/determinism.md lists the other machine-dependent paths and how they are pinned.

Each is a numpy ufunc (numba ``vectorize``: broadcasting, any shape, float64). Python floats need
none of this: ``math`` calls the C library already.
"""

from __future__ import annotations

import math

from numba import vectorize

# compiled once per machine and cached like negobs_gym.core.compiled's kernels; no fast-math
_ufunc = vectorize(["float64(float64)"], cache=True)


@_ufunc
def exp(x: float) -> float:
    """``e**x``, the C library's ``exp``."""
    return math.exp(x)


@_ufunc
def log2(x: float) -> float:
    """Base-2 logarithm, the C library's ``log2`` (NaN below 0, -inf at 0, as numpy)."""
    return math.log2(x)


@_ufunc
def tan(x: float) -> float:
    """Tangent, the C library's ``tan``."""
    return math.tan(x)


@_ufunc
def arctan(x: float) -> float:
    """Arc tangent, the C library's ``atan``."""
    return math.atan(x)


@_ufunc
def arcsin(x: float) -> float:
    """Arc sine, the C library's ``asin`` (NaN outside [-1, 1], as numpy)."""
    return math.asin(x) if -1.0 <= x <= 1.0 else math.nan


@vectorize(["float64(float64, float64)"], cache=True)
def arctan2(y: float, x: float) -> float:
    """Angle of (x, y), the C library's ``atan2``."""
    return math.atan2(y, x)
