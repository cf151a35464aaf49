"""Paper T §3.4 (Fig. 6): the region between the boundaries, minus obstacles and their shadows.

The region is the quadrilateral between the left and right boundary lines, from the LiDAR's X axis
(A1 on each side) to the farthest boundary point. The LiDAR only sees an obstacle's near face
(A2..A4 in Fig. 6); everything behind it inside its angular sector seen from the sensor origin O
(up to A5, where ray O-A4 meets the boundary) is unknown and is cut out. Grid rasterization is
vectorized over all cells: a half-plane test for the region, a polar test for each shadow.
"""

from __future__ import annotations

import numpy as np

from negobs_gym.core import libm
from negobs_gym.core.grid import GridSpec
from negobs_gym.detector.traversable.boundaries import BoundaryLine
from negobs_gym.detector.traversable.obstacles import ObstacleCluster

_EMPTY_POLY = np.zeros((0, 2))


def region_polygon(
    left: BoundaryLine | None, right: BoundaryLine | None, near_y_m: float, far_y_m: float
) -> np.ndarray:
    """Vertices (4, 2) of the region between the lines from ``near_y_m`` to ``far_y_m``, or (0, 2)."""
    if left is None or right is None or not far_y_m > near_y_m:
        return _EMPTY_POLY.copy()
    ys = np.array([near_y_m, far_y_m, far_y_m, near_y_m])
    xs = np.array([left.x_at(near_y_m), left.x_at(far_y_m), right.x_at(far_y_m), right.x_at(near_y_m)])
    return np.column_stack([xs, ys])


def region_mask(
    centres_xy_m: np.ndarray,
    left: BoundaryLine | None,
    right: BoundaryLine | None,
    near_y_m: float,
    far_y_m: float,
    axes: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Cells (rows, cols) whose centre lies in the region polygon.

    ``axes``: the centres' x (1, cols) and y (rows, 1) when the caller keeps them (a grid's
    centres share x down a column and y along a row): the same test on a row and a column.
    """
    if left is None or right is None or not far_y_m > near_y_m:
        return np.zeros(centres_xy_m.shape[:2], dtype=bool)
    x, y = (centres_xy_m[..., 0], centres_xy_m[..., 1]) if axes is None else axes
    return (y >= near_y_m) & (y <= far_y_m) & (x >= left.x_at(y)) & (x <= right.x_at(y))


def _near_face(cluster: ObstacleCluster, origin_xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bearings (clockwise from +Y) and ranges of a cluster's points from O, sorted by bearing."""
    d = cluster.points_m[:, :2] - origin_xy_m
    bearing = libm.arctan2(d[:, 0], d[:, 1])
    rng = np.hypot(d[:, 0], d[:, 1])
    order = np.argsort(bearing, kind="stable")
    return bearing[order], rng[order]


def shadow_polygon(cluster: ObstacleCluster, origin_xy_m: np.ndarray, far_range_m: float) -> np.ndarray:
    """Obstacle-plus-shadow polygon: the near face (A2..A4) then the sector's far corners."""
    bearing, rng = _near_face(cluster, origin_xy_m)
    face = origin_xy_m + np.column_stack([np.sin(bearing), np.cos(bearing)]) * rng[:, None]
    far = origin_xy_m + far_range_m * np.array(
        [[np.sin(bearing[-1]), np.cos(bearing[-1])], [np.sin(bearing[0]), np.cos(bearing[0])]]
    )
    return np.vstack([face, far])


def shadow_mask(
    cell_bearing_rad: np.ndarray,
    cell_range_m: np.ndarray,
    cluster: ObstacleCluster,
    origin_xy_m: np.ndarray,
    slack_m: float,
    cell_pad_rad: np.ndarray | None = None,
) -> np.ndarray:
    """Cells at or behind the cluster's near face inside its angular sector seen from O.

    Args:
        cell_bearing_rad: (rows, cols) bearing of each cell centre from O (clockwise from +Y).
        cell_range_m: (rows, cols) distance of each cell centre from O.
        cluster: The obstacle.
        origin_xy_m: O, the sensor origin in vehicle XY.
        slack_m: Cells this close in front of the face count as obstacle (half a cell diagonal).
        cell_pad_rad: :func:`sector_pad_rad` of these cells and ``slack_m``, when the caller keeps
            it (it depends on neither the cluster nor the frame); computed when None.
    """
    bearing, rng = _near_face(cluster, origin_xy_m)
    pad = sector_pad_rad(cell_range_m, slack_m) if cell_pad_rad is None else cell_pad_rad
    in_sector = (cell_bearing_rad >= bearing[0] - pad) & (cell_bearing_rad <= bearing[-1] + pad)
    face_range = np.interp(cell_bearing_rad, bearing, rng)
    return in_sector & (cell_range_m >= face_range - slack_m)


def sector_pad_rad(cell_range_m: np.ndarray, slack_m: float) -> np.ndarray:
    """The angle each cell subtends (``slack_m`` at its range) as seen from O: a shadow's sector is
    widened by it so the cells on the sector's edges are cut too."""
    return libm.arcsin(np.clip(slack_m / np.maximum(cell_range_m, slack_m), -1.0, 1.0))


def points_mask(grid: GridSpec, points_xy_m: np.ndarray) -> np.ndarray:
    """Cells (rows, cols) containing at least one of the points (n, 2)."""
    mask = np.zeros(grid.shape, dtype=bool)
    if points_xy_m.shape[0]:
        row, col, inside = grid.cell_of(points_xy_m)
        mask[row[inside], col[inside]] = True
    return mask
