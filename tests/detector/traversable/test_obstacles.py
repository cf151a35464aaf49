"""Obstacle candidates (d_T1) and greedy centroid clustering (d_T2), paper T §3.3."""

from __future__ import annotations

import numpy as np

from negobs_gym.detector.traversable import BoundaryLine, TraversableConfig
from negobs_gym.detector.traversable.obstacles import (
    detect_obstacles,
    greedy_clusters,
    inside_boundaries,
    obstacle_candidates,
)

CFG = TraversableConfig()


def ground_and_pole() -> np.ndarray:
    """4 layers x 41 columns: ground lines 1 m apart, a pole at columns 18..22 on layers 1..3."""
    cols = 41
    x = np.linspace(-4, 4, cols)
    pts = np.zeros((4, cols, 3))
    for layer in range(4):
        pts[layer, :, 0] = x
        pts[layer, :, 1] = 9.0 + layer
    pole = slice(18, 23)
    for layer in (1, 2, 3):
        pts[layer, pole, 1] = 10.0
        pts[layer, pole, 2] = 0.1 * layer
    return pts


def test_candidates_only_on_the_obstacle() -> None:
    q = obstacle_candidates(ground_and_pole(), CFG)
    assert q[1:4, 18:23].any(axis=0).all()
    assert not q[:, :17].any() and not q[:, 24:].any()
    assert not q[0].any()  # layer 0 hits ground 1 m in front of the pole


def test_nan_points_never_candidates() -> None:
    pts = ground_and_pole()
    pts[:, 18:23] = np.nan
    assert not obstacle_candidates(pts, CFG).any()
    assert not obstacle_candidates(np.zeros((4, 0, 3)), CFG).any()


def test_greedy_clustering_splits_far_groups_and_drops_small_ones() -> None:
    a = np.column_stack([np.linspace(-3, -2.5, 6), np.full(6, 10.0), np.zeros(6)])
    b = np.column_stack([np.linspace(2.5, 3.0, 6), np.full(6, 10.0), np.zeros(6)])
    lone = np.array([[8.0, 10.0, 0.0], [8.1, 10.0, 0.0]])
    clusters = greedy_clusters(np.vstack([a, b, lone]), CFG)
    assert len(clusters) == 2
    assert np.allclose(clusters[0].centre_xy_m, [-2.75, 10.0]) and np.allclose(
        clusters[1].centre_xy_m, [2.75, 10.0]
    )
    assert clusters[0].width_m == np.float64(0.5)
    assert greedy_clusters(np.zeros((0, 3)), CFG) == []


def test_inside_boundaries_and_detect_excludes_banks() -> None:
    pts = ground_and_pole()
    left, right = BoundaryLine(0.0, -3.0), BoundaryLine(0.0, 3.0)
    assert len(detect_obstacles(pts, left, right, CFG)) == 1
    # With the boundaries drawn left of the pole it is outside the road: no obstacle.
    assert detect_obstacles(pts, BoundaryLine(0.0, -3.0), BoundaryLine(0.0, -0.5), CFG) == []
    xy = np.array([[-2.8, 5.0], [0.0, 5.0], [2.9, 5.0]])
    assert inside_boundaries(xy, left, right, 0.3).tolist() == [False, True, False]
