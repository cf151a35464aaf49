"""Tests of the grid cubic-spline evaluation against scipy's map_coordinates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from negobs_gym.errors import GeometryError
from negobs_gym.sim.spline import cubic_spline_grid


def _reference(lattice: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    coords = np.broadcast_arrays(rows[:, None], cols[None, :])
    return ndimage.map_coordinates(lattice, coords, order=3, mode="nearest")


@pytest.mark.parametrize("cell", [1.0, 1.5, 5.0, 12.5, 37.3, 150.0])
def test_equals_map_coordinates_bit_for_bit_on_value_noise_grids(cell: float) -> None:
    rng = np.random.default_rng(int(cell * 10))
    ny, nx = 301, 97
    lattice = rng.standard_normal((math.ceil((ny - 1) / cell) + 4, math.ceil((nx - 1) / cell) + 4))
    rows, cols = np.arange(ny) / cell + 1.0, np.arange(nx) / cell + 1.0
    assert np.array_equal(cubic_spline_grid(lattice, rows, cols), _reference(lattice, rows, cols))


def test_equals_map_coordinates_at_arbitrary_points_and_the_lattice_edges() -> None:
    rng = np.random.default_rng(3)
    lattice = rng.standard_normal((9, 14))
    rows = np.concatenate([[0.0, 8.0], rng.uniform(0.0, 8.0, 40)])
    cols = np.concatenate([[0.0, 13.0], rng.uniform(0.0, 13.0, 25)])
    got = cubic_spline_grid(lattice, rows, cols)
    assert np.array_equal(got, _reference(lattice, rows, cols))
    # a cubic B-spline interpolates: the lattice values come back at the lattice points
    assert np.allclose(cubic_spline_grid(lattice, np.arange(9.0), np.arange(14.0)), lattice, atol=1e-12)


@pytest.mark.parametrize(
    ("lattice", "rows", "cols", "match"),
    [
        (np.zeros(5), [0.0], [0.0], "2-D"),
        (np.full((4, 4), np.nan), [0.0], [0.0], "finite"),
        (np.zeros((4, 4)), [-0.5], [0.0], "rows"),
        (np.zeros((4, 4)), [0.0], [3.5], "cols"),
        (np.zeros((4, 4)), [np.nan], [0.0], "rows"),
    ],
)
def test_bad_input_is_named(lattice, rows, cols, match: str) -> None:
    with pytest.raises(GeometryError, match=match):
        cubic_spline_grid(lattice, np.asarray(rows), np.asarray(cols))
