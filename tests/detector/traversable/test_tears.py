"""Hough line, tear points and boundary points (paper T §3.1)."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.detector.traversable import TraversableConfig
from negobs_gym.detector.traversable.tears import boundary_points, hough_lines, line_inliers, segment_ends

CFG = TraversableConfig()


def test_hough_finds_a_tilted_line_among_clutter() -> None:
    rng = np.random.default_rng(0)
    x = np.linspace(-5, 5, 200)
    y = 8.0 + 0.2 * x  # x cos(phi) + y sin(phi) = rho
    clutter = rng.uniform([-10, 0], [10, 20], size=(40, 2))
    xy = np.concatenate([np.column_stack([x, y]), clutter])[None]
    phi, rho = hough_lines(xy, np.ones(xy.shape[:2], dtype=bool), CFG)
    expected_phi = np.pi / 2 + np.arctan(0.2)  # normal (-0.2, 1)
    assert phi[0] == pytest.approx(expected_phi, abs=np.radians(1.0))
    inl = line_inliers(xy, np.ones(xy.shape[:2], dtype=bool), phi, rho, CFG)
    assert inl[0, :200].all()
    assert inl[0, 200:].sum() < 10


def test_hough_layer_without_points_is_nan() -> None:
    xy = np.zeros((2, 5, 2))
    valid = np.array([[True] * 5, [False] * 5])
    phi, rho = hough_lines(xy, valid, CFG)
    assert np.isfinite(phi[0]) and np.isnan(phi[1]) and np.isnan(rho[1])


def test_segment_ends_skip_short_fragments_at_the_ends() -> None:
    x = np.concatenate([[-9.0, -8.9], np.arange(-4.0, 4.01, 0.1), [8.0, 8.1, 8.2]])
    pts = np.column_stack([x, np.full(x.size, 8.0)])
    left, right = segment_ends(pts, CFG)
    assert left == pytest.approx([-4.0, 8.0]) and right == pytest.approx([4.0, 8.0])


def test_segment_ends_need_n_clean_links() -> None:
    pts = np.column_stack([np.arange(CFG.clean_run_points) * 0.1, np.zeros(CFG.clean_run_points)])
    left, right = segment_ends(pts, CFG)  # n points have only n - 1 links
    assert np.isnan(left).all() and np.isnan(right).all()
    left, _ = segment_ends(np.vstack([pts, [[0.1 * CFG.clean_run_points, 0.0]]]), CFG)
    assert left == pytest.approx([0.0, 0.0])


def test_boundary_points_of_flat_lines_between_walls() -> None:
    # 3 boundary layers + a top layer: straight ground lines from x = -3 to 3, wall points beyond.
    cols = 121
    x = np.linspace(-6, 6, cols)
    pts = np.zeros((4, cols, 3))
    for layer, y in enumerate((9.0, 10.0, 11.5, 13.0)):
        pts[layer, :, 0] = np.clip(x, -3.0, 3.0)
        pts[layer, :, 1] = np.where(np.abs(x) <= 3.0, y, y - 2.0 * (np.abs(x) - 3.0))
    ranges = np.linalg.norm(pts - np.array([0.0, 3.7, 0.65]), axis=-1)
    left, right = boundary_points(pts, ranges, CFG)
    assert left.shape == (3, 2)
    assert np.allclose(left[:, 0], -3.0, atol=0.11) and np.allclose(right[:, 0], 3.0, atol=0.11)
    # Wall points within the line tolerance still count as on the line: y within that tolerance.
    assert np.allclose(left[:, 1], [9.0, 10.0, 11.5], atol=CFG.line_tolerance_m)


def test_segment_end_at_an_occluder_is_not_a_boundary_point() -> None:
    # One layer: ground from x = -3 to 3 at y = 10, but columns right of x = 1 hit a pole at y = 8.
    cols = 61
    x = np.linspace(-3, 3, cols)
    pts = np.zeros((4, cols, 3))
    pts[..., 0] = x
    pts[..., 1] = 10.0 + np.arange(4)[:, None]
    pole = x > 1.0
    pts[0, pole, 1] = 8.0
    ranges = np.linalg.norm(pts - np.array([0.0, 3.7, 0.65]), axis=-1)
    left, right = boundary_points(pts, ranges, CFG)
    assert np.isnan(right[0]).all()  # ends at the occluder: missing, not a road edge
    assert right[1] == pytest.approx([3.0, 11.0])
    assert left[0] == pytest.approx([-3.0, 10.0])
