"""Transcendental functions from the C library, element by element, the same on every x86-64 CPU.

numpy picks its routine for some functions by the CPU it runs on: on an AVX-512 CPU float64
``arctan2``, ``exp``, ``log2``, ``arcsin``, ``arctan`` and ``tan`` run SIMD routines
(SVML) that differ from the C library's, which an AVX2 CPU runs, in the last bit for 1-10 % of
inputs. These kernels call the C library's function for every element (numba lowers ``math``
functions to libm calls), so a result depends on the C library only, not on the CPU.
docs/determinism.md lists the other machine-dependent paths and how they are pinned.

Each is a numpy ufunc (numba ``vectorize``: broadcasting, any shape, float64), built on first use:
loading one from numba's cache takes ~0.1 s, and a process that never runs the detector (an
oracle-grid training worker) needs two of the six. Python floats need none of this: ``math``
calls the C library already.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

__all__ = ["arcsin", "arctan", "arctan2", "exp", "log2", "tan"]  # noqa: F822 - built by __getattr__


def _exp(x: float) -> float:
    """``e**x``, the C library's ``exp``."""
    return math.exp(x)


def _log2(x: float) -> float:
    """Base-2 logarithm, the C library's ``log2`` (NaN below 0, -inf at 0, as numpy)."""
    return math.log2(x)


def _tan(x: float) -> float:
    """Tangent, the C library's ``tan``."""
    return math.tan(x)


def _arctan(x: float) -> float:
    """Arc tangent, the C library's ``atan``."""
    return math.atan(x)


def _arcsin(x: float) -> float:
    """Arc sine, the C library's ``asin`` (NaN outside [-1, 1], as numpy)."""
    return math.asin(x) if -1.0 <= x <= 1.0 else math.nan


def _arctan2(y: float, x: float) -> float:
    """Angle of (x, y), the C library's ``atan2``."""
    return math.atan2(y, x)


_ONE = "float64(float64)"
#: ufunc name -> (the element function, its one float64 signature: other dtypes are cast to it)
_KERNELS: dict[str, tuple[Callable[..., float], str]] = {
    "exp": (_exp, _ONE),
    "log2": (_log2, _ONE),
    "tan": (_tan, _ONE),
    "arctan": (_arctan, _ONE),
    "arcsin": (_arcsin, _ONE),
    "arctan2": (_arctan2, "float64(float64, float64)"),
}


def __getattr__(name: str) -> Any:
    """Build the ufunc ``name`` on first use (module ``__getattr__``, PEP 562) and keep it."""
    if name not in _KERNELS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from numba import vectorize

    func, signature = _KERNELS[name]
    # compiled once per machine and cached like negobs_gym.core.compiled's kernels; no fast-math
    ufunc = vectorize([signature], cache=True)(func)  # a numba DUFunc, called like a numpy ufunc
    globals()[name] = ufunc
    return ufunc


def __dir__() -> list[str]:
    return sorted([*globals(), *_KERNELS])
