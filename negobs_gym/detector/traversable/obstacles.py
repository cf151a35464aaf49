"""Paper T §3.3: obstacle points from the middle layers and greedy centroid clustering.

On the ground, adjacent LUX layers land metres apart; on an upright obstacle they land a few
centimetres apart (d_o << d_g, Fig. 4). A middle-layer point whose nearest point on an adjacent
layer (within a few columns) is closer than d_T1 joins the queue with that neighbour. The queue,
ordered by azimuth, is clustered greedily: a point joins the running cluster when it is within
d_T2 of the cluster's centroid, otherwise the cluster is closed and a new one starts with it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from negobs_gym.detector.traversable.boundaries import BoundaryLine
from negobs_gym.detector.traversable.config import TraversableConfig


@dataclass(frozen=True, eq=False)
class ObstacleCluster:
    """One obstacle: its points, centroid and width (d_oj of Eq. 12), vehicle frame [m]."""

    points_m: np.ndarray  # (k, 3)
    centre_xy_m: np.ndarray  # (2,)
    width_m: float  # twice the largest XY distance of a point from the centre


@functools.lru_cache(maxsize=8)
def _window_index(
    obstacle_layers: tuple[int, ...], lasers: int, cols: int, w: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where an obstacle layer's neighbour candidates lie in a (lasers, cols + 2w) plane padded
    with w NaN columns on each side, flattened: (layers, 2 (2w+1), cols), for column k the
    adjacent laser below's columns k + o - w, o = 0..2w, then the one above's; with the laser
    (layers, 2 (2w+1)) and the offset o - w (2 (2w+1),) of each candidate."""
    span = 2 * w + 1
    adjacent = np.array([[layer - 1] * span + [layer + 1] * span for layer in obstacle_layers])
    column = np.tile(np.arange(span), 2)
    flat = (adjacent * (cols + 2 * w) + column)[:, :, None] + np.arange(cols)
    return flat, adjacent, column - w


def obstacle_candidates(points_vehicle_m: np.ndarray, config: TraversableConfig) -> np.ndarray:
    """Mask (lasers, columns) of queued obstacle points (middle-layer hits and their neighbours)."""
    lasers, cols = points_vehicle_m.shape[:2]
    queued = np.zeros((lasers, cols), dtype=bool)
    if cols == 0:
        return queued
    w = config.neighbour_columns
    layers = tuple(config.obstacle_layers)
    # one NaN-padded (lasers, columns + 2w) plane per axis: the distances below are sums of
    # per-axis products on contiguous planes, rounded as np.linalg.norm rounds them (x^2 + y^2 +
    # z^2 in that order, then the root) at a fraction of its cost on a last axis of length 3
    padded = np.full((3, lasers, cols + 2 * w), np.nan)
    padded[:, :, w : w + cols] = points_vehicle_m.transpose(2, 0, 1)
    flat, adjacent, offsets = _window_index(layers, lasers, cols, w)
    # (3, layers, 2 (2w+1), C): the candidates of each column, the laser below's before the one
    # above's, in column order, so argmin's first minimum is the nearest with the laser below
    # winning ties (as when the two lasers were searched one after the other)
    cx, cy, cz = np.take(padded.reshape(3, -1), flat, axis=1)
    px, py, pz = padded[:, layers, None, w : w + cols]  # (layers, 1, C) each
    dx = cx - px
    dy = cy - py
    dz = cz - pz
    d = np.sqrt(dx * dx + dy * dy + dz * dz)
    d[np.isnan(d)] = np.inf
    k = d.argmin(axis=1)  # (layers, C)
    layer_of, col_of = np.nonzero(d.min(axis=1) < config.d_t1_m)  # min = d at argmin
    best = k[layer_of, col_of]
    queued[np.asarray(layers)[layer_of], col_of] = True
    queued[adjacent[layer_of, best], col_of + offsets[best]] = True
    return queued


def inside_boundaries(
    xy_m: np.ndarray, left: BoundaryLine | None, right: BoundaryLine | None, margin_m: float
) -> np.ndarray:
    """Mask of points (n, 2) at least ``margin_m`` inside both known boundary lines."""
    ok = np.ones(xy_m.shape[0], dtype=bool)
    if left is not None:
        ok &= xy_m[:, 0] >= left.x_at(xy_m[:, 1]) + margin_m
    if right is not None:
        ok &= xy_m[:, 0] <= right.x_at(xy_m[:, 1]) - margin_m
    return ok


def greedy_clusters(points_m: np.ndarray, config: TraversableConfig) -> list[ObstacleCluster]:
    """Paper T's greedy centroid clustering of queued points (k, 3), in queue order.

    The loop is over the handful of queued obstacle points only (it is inherently sequential).
    """
    clusters: list[ObstacleCluster] = []
    if points_m.shape[0] == 0:
        return clusters
    xs = points_m[:, 0].tolist()  # plain floats: the sequential loop is ~10x faster than numpy
    ys = points_m[:, 1].tolist()
    labels = np.empty(points_m.shape[0], dtype=np.int64)
    label, count = 0, 1
    cx, cy = xs[0], ys[0]
    labels[0] = 0
    d2 = config.d_t2_m * config.d_t2_m
    for i in range(1, len(xs)):
        dx, dy = xs[i] - cx, ys[i] - cy
        if dx * dx + dy * dy < d2:
            count += 1
            cx += dx / count
            cy += dy / count
        else:
            label += 1
            cx, cy, count = xs[i], ys[i], 1
        labels[i] = label
    for lab in range(label + 1):
        members = points_m[labels == lab]
        if members.shape[0] < config.min_cluster_points:
            continue
        c = members[:, :2].mean(axis=0)
        width = 2.0 * float(np.max(np.linalg.norm(members[:, :2] - c, axis=1)))
        clusters.append(ObstacleCluster(points_m=members, centre_xy_m=c, width_m=width))
    return clusters


def detect_obstacles(
    points_vehicle_m: np.ndarray,
    left: BoundaryLine | None,
    right: BoundaryLine | None,
    config: TraversableConfig,
) -> list[ObstacleCluster]:
    """Obstacle clusters inside the boundaries (paper T §3.3)."""
    queued = obstacle_candidates(points_vehicle_m, config)
    lasers, _cols = queued.shape
    # Queue in azimuth order (column-major), then layer: a sweep across the scene.
    order = np.flatnonzero(queued.T.ravel())
    col, layer = np.divmod(order, lasers)
    pts = points_vehicle_m[layer, col]
    pts = pts[inside_boundaries(pts[:, :2], left, right, config.obstacle_inside_margin_m)]
    return greedy_clusters(pts, config)
