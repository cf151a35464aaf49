"""Paper T §3.2: least-squares left and right boundary lines from filtered boundary points.

Paper T writes the line as ``y = b x + k``; the road boundaries of a forward-looking LUX are close
to the vehicle Y axis, where that form is ill-conditioned, so we fit the equivalent lateral form
``x = slope * y + offset`` (same least squares, well-conditioned for near-vertical boundaries).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.core.geometry import vehicle_to_world_xy, world_to_vehicle_xy
from negobs_gym.core.pose import Pose


@dataclass(frozen=True)
class BoundaryLine:
    """A boundary ``x = slope * y + offset`` in the vehicle frame [m]; slope > 0 leans right."""

    slope: float
    offset_m: float

    def x_at(self, y_m: np.ndarray | float) -> np.ndarray:
        """Lateral position of the boundary at forward distance ``y_m``."""
        return self.slope * np.asarray(y_m, dtype=np.float64) + self.offset_m

    def distance(self, xy_m: np.ndarray) -> np.ndarray:
        """Perpendicular distance of points (..., 2) to the line [m]."""
        xy = np.asarray(xy_m, dtype=np.float64)
        return np.abs(xy[..., 0] - self.slope * xy[..., 1] - self.offset_m) / np.hypot(1.0, self.slope)


def fit_boundary(points_xy_m: np.ndarray) -> BoundaryLine | None:
    """Least-squares line through the finite rows of ``points_xy_m`` (k, 2).

    One point gives a line parallel to the vehicle Y axis through it; none gives ``None``; points
    that share one y (a degenerate fit) also give the parallel line through their mean.
    """
    pts = np.asarray(points_xy_m, dtype=np.float64).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.shape[0] == 0:
        return None
    mean = pts.mean(axis=0)
    dy = pts[:, 1] - mean[1]
    syy = float(dy @ dy)
    if pts.shape[0] == 1 or syy < 1e-9:
        return BoundaryLine(0.0, float(mean[0]))
    slope = float(dy @ (pts[:, 0] - mean[0])) / syy
    return BoundaryLine(slope, float(mean[0] - slope * mean[1]))


def carry_along_line(
    points_xy_m: np.ndarray,
    line: BoundaryLine | None,
    before: Pose,
    after: Pose,
    max_angle_deg: float = 60.0,
) -> np.ndarray:
    """Where boundary points (k, 2) seen at pose ``before`` lie in the vehicle frame at ``after``:
    on ``line`` (the side's boundary at ``before``; None: parallel to that frame's +Y), moved into
    the new frame, at each point's old forward distance y. The move is planar (yaw and x, y).

    Not in paper T (F = I). A layer's boundary point is where that layer meets the road's edge, at
    a distance fixed by the layer's elevation, so y stays; x follows the edge (straight between
    frames) as the car turns and moves. Where the moved line is more than ``max_angle_deg`` off
    the new +Y axis it is no lateral boundary (and x on it ill-defined): NaN.
    """
    slope = 0.0 if line is None else line.slope
    offset = 0.0 if line is None else line.offset_m
    pts = np.asarray(points_xy_m, dtype=np.float64)
    on_line = np.array([[offset, 0.0], [slope + offset, 1.0]])  # two points of the line, 1 m apart in y
    world = vehicle_to_world_xy(np.concatenate([pts, on_line]), (before.x, before.y), before.yaw)
    local = world_to_vehicle_xy(world, (after.x, after.y), after.yaw)
    moved, (start, end) = local[:-2], local[-2:]
    direction = (end - start) / np.hypot(*(end - start))
    if direction[1] < math.cos(math.radians(max_angle_deg)):
        return np.full_like(pts, np.nan)
    along = (pts[:, 1] - moved[:, 1]) / direction[1]
    return moved + along[:, None] * direction


def passes_on_its_side(
    line: BoundaryLine, side: int, sensor_xy_m: tuple[float, float], clearance_m: float
) -> bool:
    """Whether ``line``, a boundary of ``side`` (-1 left, +1 right), passes the sensor at least
    ``clearance_m`` out on that side at the sensor's forward distance (paper T's A1: the boundaries
    meet the LiDAR's X axis on either side of it; not a check paper T makes)."""
    x, y = sensor_xy_m
    return bool(side * (float(line.x_at(y)) - x) >= clearance_m)


def drop_inconsistent(points_xy_m: np.ndarray, max_deviation_m: float) -> np.ndarray:
    """NaN out boundary points (k, 2) whose x is > ``max_deviation_m`` from the median x.

    Not in paper T: the layers' ends of one side lie on one road edge, so with three or more
    points a lone end far from the others was cut short (a bump's shadow, an occluder). With fewer
    than three points no majority exists and nothing is dropped.
    """
    pts = np.array(points_xy_m, dtype=np.float64)
    x = pts[:, 0]
    finite = np.isfinite(x)
    if finite.sum() < 3:
        return pts
    bad = finite & (np.abs(x - np.median(x[finite])) > max_deviation_m)
    pts[bad] = np.nan
    return pts
