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


def candidates_reference(points: np.ndarray, config: TraversableConfig) -> np.ndarray:
    """obstacle_candidates point by point: for each obstacle-layer point its nearest neighbour
    among the adjacent lasers' columns within +-w (laser below first, then column order: the first
    of equal distances wins), queued with it when nearer than d_T1; NaN points are never near."""
    lasers, cols = points.shape[:2]
    queued = np.zeros((lasers, cols), dtype=bool)
    w = config.neighbour_columns
    for layer in config.obstacle_layers:
        for k in range(cols):
            best, where = np.inf, None
            for adj in (layer - 1, layer + 1):
                for c in range(k - w, k + w + 1):
                    if 0 <= c < cols:
                        d = float(np.linalg.norm(points[adj, c] - points[layer, k]))
                        if d < best:  # NaN compares False
                            best, where = d, (adj, c)
            if best < config.d_t1_m:
                queued[layer, k] = True
                queued[where] = True
    return queued


def test_candidates_match_the_point_by_point_search() -> None:
    # Random clouds with NaN holes, a pole and repeated points (ties between the two adjacent
    # lasers and between columns), several widths of window.
    rng = np.random.default_rng(11)
    for w, cols in [(2, 41), (1, 7), (3, 3), (2, 1)]:
        config = TraversableConfig(neighbour_columns=w)
        for _ in range(5):
            pts = rng.normal(0.0, 0.15, (4, cols, 3)) + np.array([0.0, 10.0, 0.0])
            pts[rng.random((4, cols)) < 0.15] = np.nan
            pts[0, : cols // 2] = pts[2, : cols // 2]  # equal distances from layer 1 below and above
            pts[3, cols // 3 :] = pts[1, cols // 3 :]  # and from layer 2
            assert np.array_equal(obstacle_candidates(pts, config), candidates_reference(pts, config))
    pole = ground_and_pole()
    assert np.array_equal(obstacle_candidates(pole, CFG), candidates_reference(pole, CFG))
