"""The C library's transcendental functions, element by element (negobs_gym.core.libm)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.core import libm

RNG = np.random.default_rng(0)
X = RNG.uniform(-10.0, 10.0, 20_000)
Y = RNG.uniform(-10.0, 10.0, 20_000)


@pytest.mark.parametrize(
    ("ours", "c_library", "x"),
    [
        (libm.exp, math.exp, X),
        (libm.log2, math.log2, np.abs(X) + 1e-9),
        (libm.tan, math.tan, X),
        (libm.arctan, math.atan, X),
        (libm.arcsin, math.asin, X / 10.0),
    ],
)
def test_unary_functions_equal_the_c_library_bit_for_bit(ours, c_library, x):
    got = ours(x)
    assert got.dtype == np.float64 and got.shape == x.shape
    np.testing.assert_array_equal(got, [c_library(v) for v in x])


def test_arctan2_equals_the_c_library_and_broadcasts():
    np.testing.assert_array_equal(libm.arctan2(Y, X), [math.atan2(y, x) for y, x in zip(Y, X, strict=True)])
    grid = libm.arctan2(Y[:3, None], X[None, :4])
    assert grid.shape == (3, 4)
    assert grid[2, 1] == math.atan2(Y[2], X[1])
    assert libm.arctan2(1.0, 0.0) == math.pi / 2  # scalars give 0-d arrays


def test_shapes_and_numpy_domain_rules():
    assert libm.exp(np.zeros((2, 3))).shape == (2, 3)
    np.testing.assert_array_equal(libm.arcsin(np.array([2.0, -1.0])), [np.nan, -math.pi / 2])
    with pytest.warns(RuntimeWarning, match="invalid value"):  # numpy's warning, as np.log2 gives
        assert np.isnan(libm.log2(np.array([-1.0])))[0]
    with pytest.warns(RuntimeWarning, match="divide by zero"):
        assert libm.log2(np.array([0.0]))[0] == -np.inf
    assert libm.exp(np.array([np.nan]))[0] != libm.exp(np.array([np.nan]))[0]  # NaN stays NaN


def test_a_kernel_is_built_on_first_use_only() -> None:
    """Importing the module builds none of the six (each costs ~0.1 s from numba's cache)."""
    import subprocess
    import sys

    code = (
        "import negobs_gym.core.libm as m, numpy as np\n"
        "assert not {'exp', 'arctan2'} & set(vars(m))\n"
        "assert m.exp(np.array([0.0]))[0] == 1.0 and 'exp' in vars(m) and 'arctan2' not in vars(m)\n"
        "assert 'arctan2' in dir(m)\n"
        "try:\n    m.cos\nexcept AttributeError:\n    pass\nelse:\n    raise SystemExit('no error')\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
