"""The kernel decorator's promises: numpy's arithmetic bit for bit, numpy's division by zero."""

from __future__ import annotations

import numpy as np

from negobs_gym.core.compiled import kernel


@kernel
def _multiply_add(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    out = np.empty_like(a)
    for k in range(a.size):
        out[k] = a[k] * b[k] + c[k]  # contracted into one FMA, it would round once, not twice
    return out


@kernel
def _divide(a: float, b: float) -> float:
    return a / b


def test_kernels_round_each_operation_as_numpy_does():
    rng = np.random.default_rng(0)
    a, b, c = (rng.normal(size=100_000) for _ in range(3))
    want = a * b + c
    np.testing.assert_array_equal(_multiply_add(a, b, c), want)  # an FMA would differ in ~1/4 of rows


def test_kernels_divide_by_zero_as_numpy_does():
    assert _divide(1.0, 0.0) == np.inf
    assert np.isnan(_divide(0.0, 0.0))
