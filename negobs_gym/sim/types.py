"""Terrain data: the heightfield, the track and the ground-truth obstacle records.

Pure data (numpy only), shared by the terrain generator, the PyBullet world, the ray casters, the
renderer and the evaluation. All coordinates are in the world frame (Z up), SI units.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from negobs_gym.core import libm
from negobs_gym.core.geometry import polyline_stations, vehicle_to_world_xy
from negobs_gym.errors import GeometryError

NegativeKind = Literal["pit", "ditch", "trench", "crater"]
PositiveKind = Literal["rock", "box", "mound", "vehicle", "motorbike", "pedestrian", "pole"]
PrimitiveShape = Literal["box", "cylinder"]


@dataclass(frozen=True, eq=False)
class HeightField:
    """Regular grid of terrain heights.

    ``heights_m[j, i]`` is the world Z of the sample at
    ``x = origin_m[0] + i * resolution_m``, ``y = origin_m[1] + j * resolution_m``.
    """

    heights_m: np.ndarray  # (ny, nx) float32
    resolution_m: float
    origin_m: tuple[float, float]

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx)."""
        return self.heights_m.shape  # type: ignore[return-value]

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) covered by the samples."""
        ny, nx = self.heights_m.shape
        x0, y0 = self.origin_m
        return x0, x0 + (nx - 1) * self.resolution_m, y0, y0 + (ny - 1) * self.resolution_m

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """Bilinearly interpolated height at world points (..., 2); NaN outside the grid."""
        xy = np.asarray(xy, dtype=np.float64)
        ny, nx = self.heights_m.shape
        fx = (xy[..., 0] - self.origin_m[0]) / self.resolution_m
        fy = (xy[..., 1] - self.origin_m[1]) / self.resolution_m
        inside = (fx >= 0) & (fx <= nx - 1) & (fy >= 0) & (fy <= ny - 1)
        i0 = np.clip(np.floor(fx).astype(np.int64), 0, max(nx - 2, 0))
        j0 = np.clip(np.floor(fy).astype(np.int64), 0, max(ny - 2, 0))
        tx, ty = np.clip(fx - i0, 0, 1), np.clip(fy - j0, 0, 1)
        h = self.heights_m
        i1, j1 = np.minimum(i0 + 1, nx - 1), np.minimum(j0 + 1, ny - 1)
        z = (
            h[j0, i0] * (1 - tx) * (1 - ty)
            + h[j0, i1] * tx * (1 - ty)
            + h[j1, i0] * (1 - tx) * ty
            + h[j1, i1] * tx * ty
        )
        return np.where(inside, z, np.nan)


@dataclass(frozen=True, eq=False)
class NegativeObstacle:
    """Ground truth of one carved negative obstacle (docs/terrain.md)."""

    obstacle_id: str
    kind: NegativeKind
    outline_xy_m: np.ndarray  # (N, 2) world-frame rim polygon, counter-clockwise
    depth_m: float  # rim to floor [m]
    floor_z_m: float  # world Z of the floor [m]
    wall_slope_deg: float = 90.0  # wall angle from horizontal; 90 = vertical walls

    @property
    def centre_xy_m(self) -> np.ndarray:
        """Centroid of the outline vertices."""
        return np.asarray(self.outline_xy_m).mean(axis=0)


@dataclass(frozen=True, eq=False)
class PositiveObstacle:
    """Ground truth of one positive obstacle, built as a static PyBullet primitive."""

    obstacle_id: str
    kind: PositiveKind
    shape: PrimitiveShape
    centre_m: np.ndarray  # (3,) world position of the primitive's centre
    half_extents_m: np.ndarray  # box: (hx, hy, hz); cylinder: (radius, radius, half_height)
    yaw_rad: float = 0.0
    # True when the obstacle is already part of the heightfield (e.g. a mound): the world must not
    # build a body for it; the record is ground truth only.
    in_heightfield: bool = False

    @property
    def footprint_xy_m(self) -> np.ndarray:
        """World xy footprint polygon: the box's 4 corners (body X right, Y forward, yawed), or a
        16-gon for a cylinder."""
        hx, hy = float(self.half_extents_m[0]), float(self.half_extents_m[1])
        if self.shape == "box":
            local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        else:
            t = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
            local = np.stack([hx * np.cos(t), hx * np.sin(t)], axis=1)
        return vehicle_to_world_xy(local, (float(self.centre_m[0]), float(self.centre_m[1])), self.yaw_rad)


@dataclass(frozen=True, eq=False)
class Track:
    """The drivable track: a centre line and a width, plus its borders (docs/terrain.md).

    Track coordinates: ``station_m`` is the distance along the centre line from its first vertex
    (the start), ``lateral_m`` the signed offset from it, positive to the RIGHT of the driving
    direction (the vehicle's +X when it drives along the track). Beyond either end the first/last
    segment is extended in a straight line.
    """

    centreline_xy_m: np.ndarray  # (N, 2) world polyline, in driving order
    width_m: float
    border_kinds: tuple[str, str] = ("verge", "verge")  # (left, right) border of the track

    @functools.cached_property
    def stations_m(self) -> np.ndarray:
        """Cumulative distance along the centre line at each vertex, (N,) starting at 0 (read-only:
        computed once per track)."""
        stations = polyline_stations(self.centreline_xy_m)
        stations.flags.writeable = False
        return stations

    @property
    def length_m(self) -> float:
        """Length of the centre line [m]."""
        return float(self.stations_m[-1])

    def pose_at(
        self, station_m: np.ndarray | float, lateral_m: np.ndarray | float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """World xy (..., 2) and yaw [rad] (...) of track coordinates.

        The yaw follows :mod:`negobs_gym.core.pose`: yaw 0 faces world +Y, forward direction is
        ``(-sin yaw, cos yaw)``.
        """
        pts = np.asarray(self.centreline_xy_m, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[0] < 2 or pts.shape[1] != 2:
            raise GeometryError(f"centreline_xy_m must be (N>=2, 2), got {pts.shape}")
        st = self.stations_m
        s = np.asarray(station_m, dtype=np.float64)
        lat = np.asarray(lateral_m, dtype=np.float64)
        k = np.clip(np.searchsorted(st, s, side="right") - 1, 0, len(st) - 2)
        d = pts[k + 1] - pts[k]
        seg_len = np.linalg.norm(d, axis=-1)
        t = d / np.maximum(seg_len, 1e-12)[..., None]
        xy = pts[k] + t * (s - st[k])[..., None]
        right = np.stack([t[..., 1], -t[..., 0]], axis=-1)
        xy = xy + right * lat[..., None]
        yaw = libm.arctan2(-t[..., 0], t[..., 1])
        return xy, yaw


@dataclass(frozen=True, eq=False)
class Terrain:
    """Everything the world builds and the evaluation checks against, from one seed."""

    heightfield: HeightField
    track: Track
    negative_obstacles: tuple[NegativeObstacle, ...] = ()
    positive_obstacles: tuple[PositiveObstacle, ...] = ()
    start_xy_yaw: tuple[float, float, float] = (0.0, 0.0, 0.0)  # start pose (x, y, yaw [rad])
    goal_xy_m: tuple[float, float] = (0.0, 0.0)
    seed: int | None = None
    metadata: dict = field(default_factory=dict)
