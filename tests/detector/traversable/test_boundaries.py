"""Least-squares boundary lines (paper T §3.2)."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.detector.traversable import BoundaryLine, fit_boundary


def test_fit_recovers_line_and_ignores_nan_rows() -> None:
    y = np.array([9.0, 10.0, 11.5, np.nan])
    x = 0.3 * y - 4.0
    line = fit_boundary(np.column_stack([x, y]))
    assert line.slope == pytest.approx(0.3) and line.offset_m == pytest.approx(-4.0)
    assert line.x_at(10.0) == pytest.approx(-1.0)


def test_fit_degenerate_cases() -> None:
    assert fit_boundary(np.full((3, 2), np.nan)) is None
    assert fit_boundary(np.zeros((0, 2))) is None
    one = fit_boundary(np.array([[2.0, 9.0]]))
    assert one == BoundaryLine(0.0, 2.0)
    same_y = fit_boundary(np.array([[1.0, 9.0], [3.0, 9.0]]))
    assert same_y == BoundaryLine(0.0, 2.0)


def test_distance_is_perpendicular() -> None:
    line = BoundaryLine(1.0, 0.0)  # x = y
    assert line.distance(np.array([1.0, 0.0])) == pytest.approx(np.sqrt(0.5))


def test_drop_inconsistent_needs_a_majority() -> None:
    from negobs_gym.detector.traversable.boundaries import drop_inconsistent

    pts = np.array([[-4.0, 9.0], [-1.2, 10.0], [-4.1, 11.0]])
    out = drop_inconsistent(pts, 1.0)
    assert np.isnan(out[1]).all() and np.array_equal(out[[0, 2]], pts[[0, 2]])
    two = np.array([[-4.0, 9.0], [-1.2, 10.0], [np.nan, np.nan]])
    assert np.array_equal(drop_inconsistent(two, 1.0), two, equal_nan=True)
