"""Negative obstacles carved into a heightfield, positive obstacles placed on it.

Each carve returns a new :class:`HeightField` and the obstacle's ground-truth record, so the
terrain the world builds and the record the evaluation checks can never disagree: the floor of a
carved obstacle is flat at ``floor_z_m = rim height - depth``, where the rim height is the mean
surface height sampled along the outline before carving.

Obstacle sizes follow paper N §4 (pits of 100x50, 100x80, 150x60 and 100x100 cm, minimum width
30 cm) and docs/terrain.md (depth 0.3-1.5 m). ``length_m`` is measured along the obstacle's heading
(for track placement: along the track), ``width_m`` across it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import get_args

import numpy as np

from negobs_gym.errors import ConfigError, require
from negobs_gym.sim.types import (
    HeightField,
    NegativeKind,
    NegativeObstacle,
    PositiveKind,
    PositiveObstacle,
)

NEGATIVE_KINDS: tuple[str, ...] = get_args(NegativeKind)
POSITIVE_KINDS: tuple[str, ...] = get_args(PositiveKind)

# Default (length along heading, width across, height) [m] of each positive kind.
POSITIVE_DEFAULT_SIZES_M: dict[str, tuple[float, float, float]] = {
    "rock": (0.8, 0.6, 0.5),
    "box": (1.0, 1.0, 1.0),
    "mound": (4.0, 3.0, 0.6),
    "vehicle": (4.5, 1.8, 1.5),  # a parked car (issue 2)
    "motorbike": (2.0, 0.8, 1.2),  # paper T's parked-motorbike scene
    "pedestrian": (0.6, 0.6, 1.7),  # cylinder r 0.3 m, h 1.7 m (issue 2)
}

# Paper N §4: sizes (length x width) [m] of the pits in its test scenes.
PAPER_N_PIT_SIZES_M: tuple[tuple[float, float], ...] = ((1.0, 0.5), (1.0, 0.8), (1.5, 0.6), (1.0, 1.0))
MIN_NEGATIVE_WIDTH_M = 0.3  # paper N §3.1 (Eq. 14): minimum negative-obstacle width w_min
DEPTH_RANGE_M = (0.3, 1.5)  # docs/terrain.md

_CRATER_VERTICES = 48


def _finite(value: float) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


@dataclass(frozen=True, kw_only=True)
class ObstaclePlacement:
    """Where an obstacle goes, shared by the negative and positive specs.

    Either track coordinates (``station_m`` = distance of the obstacle's CENTRE along the track from
    the start, ``lateral_m`` = offset of the centre, + to the right) with ``yaw_deg`` relative to
    the track heading, or world coordinates (``xy_m``) with ``yaw_deg`` the world yaw of the
    obstacle's length axis (0 = along world +Y).
    """

    station_m: float | None = None
    lateral_m: float = 0.0
    xy_m: tuple[float, float] | None = None
    yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        require(
            (self.station_m is None) != (self.xy_m is None),
            "station_m",
            "give exactly one placement: station_m (track coordinates) or xy_m (world)",
        )
        if self.station_m is not None:
            require(_finite(self.station_m), "station_m", f"must be finite, got {self.station_m!r}")
        if self.xy_m is not None:
            require(
                len(self.xy_m) == 2 and all(_finite(v) for v in self.xy_m),
                "xy_m",
                f"must be two finite numbers, got {self.xy_m!r}",
            )
        require(_finite(self.lateral_m), "lateral_m", f"must be finite, got {self.lateral_m!r}")
        require(_finite(self.yaw_deg), "yaw_deg", f"must be finite, got {self.yaw_deg!r}")


@dataclass(frozen=True, kw_only=True)
class NegativeObstacleSpec(ObstaclePlacement):
    """One negative obstacle to carve; placement as in :class:`ObstaclePlacement`."""

    kind: str = "pit"  # one of NEGATIVE_KINDS; "crater" is elliptical, the others rectangular
    length_m: float = 1.0  # along the heading [m]; paper N §4 pits are 1.0-1.5 m long
    width_m: float = 0.5  # across the heading [m]; paper N §3.1 minimum width 0.3 m
    depth_m: float = 0.8  # rim to floor [m]; docs/terrain.md: 0.3-1.5 m
    wall_slope_deg: float = 90.0  # wall angle from horizontal; 90 = vertical walls

    def __post_init__(self) -> None:
        super().__post_init__()
        require(
            self.kind in NEGATIVE_KINDS,
            "kind",
            f"unknown negative obstacle kind {self.kind!r}; expected one of {NEGATIVE_KINDS}",
        )
        for name in ("length_m", "width_m", "depth_m"):
            value = getattr(self, name)
            require(_finite(value) and value > 0, name, f"must be finite and > 0, got {value!r}")
        require(
            _finite(self.wall_slope_deg) and 0 < self.wall_slope_deg <= 90,
            "wall_slope_deg",
            f"must be in (0, 90], got {self.wall_slope_deg!r}",
        )


@dataclass(frozen=True, kw_only=True)
class PositiveObstacleSpec(ObstaclePlacement):
    """One positive obstacle; placement as in :class:`ObstaclePlacement`.

    ``size_m`` is (length along heading, width across, height) [m]; None takes the kind's default
    from :data:`POSITIVE_DEFAULT_SIZES_M`. Pedestrians are cylinders of diameter ``size_m[0]``;
    mounds are raised into the heightfield (smooth cosine bump) and recorded with
    ``in_heightfield=True``; every other kind is a box the world builds as a static body.
    """

    kind: str = "rock"
    size_m: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        require(
            self.kind in POSITIVE_KINDS,
            "kind",
            f"unknown positive obstacle kind {self.kind!r}; expected one of {POSITIVE_KINDS}",
        )
        if self.size_m is not None:
            require(
                len(self.size_m) == 3 and all(_finite(v) and v > 0 for v in self.size_m),
                "size_m",
                f"must be three finite sizes > 0, got {self.size_m!r}",
            )

    @property
    def resolved_size_m(self) -> tuple[float, float, float]:
        """The size used: ``size_m`` or the kind's default."""
        return self.size_m if self.size_m is not None else POSITIVE_DEFAULT_SIZES_M[self.kind]


def sample_pit_spec(
    rng: np.random.Generator,
    *,
    station_m: float,
    lateral_m: float = 0.0,
    size_jitter: float = 0.2,
    depth_range_m: tuple[float, float] = DEPTH_RANGE_M,
) -> NegativeObstacleSpec:
    """A pit of one of paper N's sizes, each side scaled by a factor in ``1 +- size_jitter``.

    Widths never go below :data:`MIN_NEGATIVE_WIDTH_M`; the depth is uniform in
    ``depth_range_m``. Draws exactly four numbers from ``rng``.
    """
    require(
        _finite(size_jitter) and 0 <= size_jitter < 1,
        "size_jitter",
        f"must be in [0, 1), got {size_jitter!r}",
    )
    lo, hi = depth_range_m
    require(
        _finite(lo) and _finite(hi) and 0 < lo <= hi,
        "depth_range_m",
        f"must be (low, high) with 0 < low <= high, got {depth_range_m!r}",
    )
    length, width = PAPER_N_PIT_SIZES_M[int(rng.integers(len(PAPER_N_PIT_SIZES_M)))]
    scale = rng.uniform(1.0 - size_jitter, 1.0 + size_jitter, size=2)
    return NegativeObstacleSpec(
        kind="pit",
        length_m=float(length * scale[0]),
        width_m=float(max(width * scale[1], MIN_NEGATIVE_WIDTH_M)),
        depth_m=float(rng.uniform(lo, hi)),
        station_m=station_m,
        lateral_m=lateral_m,
    )


def _axes(yaw_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of the length axis (forward at this yaw) and the width axis (to its right)."""
    fwd = np.array([-math.sin(yaw_rad), math.cos(yaw_rad)])
    right = np.array([fwd[1], -fwd[0]])
    return fwd, right


def _ccw(poly: np.ndarray) -> np.ndarray:
    x, y = poly[:, 0], poly[:, 1]
    area2 = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    return poly if area2 > 0 else poly[::-1].copy()


def obstacle_outline(
    kind: str, length_m: float, width_m: float, centre_xy_m: np.ndarray, yaw_rad: float
) -> np.ndarray:
    """World outline (N, 2), counter-clockwise: a rectangle, or an ellipse for craters."""
    fwd, right = _axes(yaw_rad)
    if kind == "crater":
        t = np.linspace(0.0, 2 * np.pi, _CRATER_VERTICES, endpoint=False)
        a = 0.5 * length_m * np.cos(t)
        b = 0.5 * width_m * np.sin(t)
    else:
        a = 0.5 * length_m * np.array([-1.0, 1.0, 1.0, -1.0])
        b = 0.5 * width_m * np.array([-1.0, -1.0, 1.0, 1.0])
    poly = np.asarray(centre_xy_m, dtype=np.float64) + a[:, None] * fwd + b[:, None] * right
    return _ccw(poly)


def points_in_polygon(xy_m: np.ndarray, polygon_xy_m: np.ndarray) -> np.ndarray:
    """Boolean mask (...) of points (..., 2) inside a simple polygon (N, 2) (even-odd rule).

    Vectorised over points and edges (memory ~ points x edges); for outlines of a few dozen
    vertices, as the obstacle records have.
    """
    pts = np.asarray(xy_m, dtype=np.float64)
    poly = np.asarray(polygon_xy_m, dtype=np.float64)
    if pts.shape[-1:] != (2,) or poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 3:
        raise ValueError(f"need points (..., 2) and a polygon (N>=3, 2), got {pts.shape} and {poly.shape}")
    x = pts[..., 0, None]
    y = pts[..., 1, None]
    x1, y1 = poly[:, 0], poly[:, 1]
    x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
    straddles = (y1 > y) != (y2 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
    crossings = np.count_nonzero(straddles & (x < x_cross), axis=-1)
    return crossings % 2 == 1


def _window(hf: HeightField, outline: np.ndarray, field: str) -> tuple[slice, slice, np.ndarray, np.ndarray]:
    """Index window of the samples under ``outline`` and their world x, y; errors if outside."""
    x0, x1, y0, y1 = hf.extent_m
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    r = hf.resolution_m
    if lo[0] < x0 + r or hi[0] > x1 - r or lo[1] < y0 + r or hi[1] > y1 - r:
        raise ConfigError(
            field,
            f"obstacle spans x {lo[0]:.2f}..{hi[0]:.2f} m, y {lo[1]:.2f}..{hi[1]:.2f} m, outside "
            f"the terrain x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m (one-cell margin)",
        )
    i0 = int(np.floor((lo[0] - hf.origin_m[0]) / r))
    i1 = int(np.ceil((hi[0] - hf.origin_m[0]) / r)) + 1
    j0 = int(np.floor((lo[1] - hf.origin_m[1]) / r))
    j1 = int(np.ceil((hi[1] - hf.origin_m[1]) / r)) + 1
    xs = hf.origin_m[0] + r * np.arange(i0, i1)
    ys = hf.origin_m[1] + r * np.arange(j0, j1)
    gx, gy = np.meshgrid(xs, ys)
    return slice(j0, j1), slice(i0, i1), gx, gy


def _local(gx: np.ndarray, gy: np.ndarray, centre: np.ndarray, yaw_rad: float):
    fwd, right = _axes(yaw_rad)
    dx, dy = gx - centre[0], gy - centre[1]
    return dx * fwd[0] + dy * fwd[1], dx * right[0] + dy * right[1]


def _rim_height(hf: HeightField, outline: np.ndarray) -> float:
    """Mean surface height sampled along the closed outline, every half cell."""
    closed = np.vstack([outline, outline[:1]])
    seg = np.diff(closed, axis=0)
    n = np.maximum(np.ceil(np.linalg.norm(seg, axis=1) / (0.5 * hf.resolution_m)), 1).astype(int)
    k = np.repeat(np.arange(len(seg)), n)
    t = np.concatenate([np.arange(m) / m for m in n])
    pts = closed[k] + seg[k] * t[:, None]
    return float(np.mean(hf.height_at(pts)))


def carve_negative_obstacle(
    heightfield: HeightField,
    spec: NegativeObstacleSpec,
    *,
    centre_xy_m: np.ndarray,
    yaw_rad: float,
    obstacle_id: str,
    field: str = "spec",
) -> tuple[HeightField, NegativeObstacle]:
    """Carve one negative obstacle; returns the new heightfield and the ground-truth record.

    Samples strictly inside the outline's floor region are set to ``floor_z_m``; with sloped walls
    (``wall_slope_deg`` < 90) the samples between rim and floor follow the wall and are never
    raised. Samples outside the outline are untouched.

    Raises:
        ConfigError: the obstacle is smaller than two samples or lies outside the terrain
            (``field`` prefixes the offending field name, e.g. ``"negative_obstacles[0]"``).
    """
    r = heightfield.resolution_m
    for name in ("length_m", "width_m"):
        size = getattr(spec, name)
        require(
            size >= 2 * r,
            f"{field}.{name}",
            f"{size} m is below two heightfield samples ({2 * r} m) and cannot be carved",
        )
    centre = np.asarray(centre_xy_m, dtype=np.float64)
    outline = obstacle_outline(spec.kind, spec.length_m, spec.width_m, centre, yaw_rad)
    place_field = f"{field}.{'station_m' if spec.station_m is not None else 'xy_m'}"
    rows, cols, gx, gy = _window(heightfield, outline, place_field)
    rim_z = _rim_height(heightfield, outline)
    floor_z = rim_z - spec.depth_m

    a, b = _local(gx, gy, centre, yaw_rad)
    half_l, half_w = 0.5 * spec.length_m, 0.5 * spec.width_m
    eps = 1e-9
    if spec.kind == "crater":
        # Inside the recorded (inscribed) polygon, so carving and ground truth agree exactly.
        inside = points_in_polygon(np.stack([gx, gy], axis=-1), outline)
        rho = np.sqrt((a / half_l) ** 2 + (b / half_w) ** 2)
        dist_in = (1.0 - rho) * min(half_l, half_w)
    else:
        inside = (np.abs(a) <= half_l + eps) & (np.abs(b) <= half_w + eps)
        dist_in = np.minimum(half_l - np.abs(a), half_w - np.abs(b))

    heights = heightfield.heights_m.copy()
    window = heights[rows, cols]
    if spec.wall_slope_deg >= 90.0:
        carved = np.full_like(window, floor_z)
    else:
        wall_z = rim_z - math.tan(math.radians(spec.wall_slope_deg)) * np.maximum(dist_in, 0.0)
        carved = np.where(wall_z <= floor_z, floor_z, np.minimum(window, wall_z))
    heights[rows, cols] = np.where(inside, carved, window).astype(heights.dtype)

    record = NegativeObstacle(
        obstacle_id=obstacle_id,
        kind=spec.kind,  # type: ignore[arg-type]
        outline_xy_m=outline,
        depth_m=float(spec.depth_m),
        floor_z_m=float(np.float32(floor_z)),
        wall_slope_deg=float(spec.wall_slope_deg),
    )
    return HeightField(heights, r, heightfield.origin_m), record


def place_positive_obstacle(
    heightfield: HeightField,
    spec: PositiveObstacleSpec,
    *,
    centre_xy_m: np.ndarray,
    yaw_rad: float,
    obstacle_id: str,
    field: str = "spec",
) -> tuple[HeightField, PositiveObstacle]:
    """Place one positive obstacle on the ground; mounds are raised into the heightfield.

    The primitive's bottom is at the lowest ground height under its footprint, so no gap shows
    under it. Returns the (possibly new) heightfield and the ground-truth record.
    """
    length, width, height = spec.resolved_size_m
    centre = np.asarray(centre_xy_m, dtype=np.float64)
    footprint_kind = "crater" if spec.kind in ("pedestrian", "mound") else "box"
    outline = obstacle_outline(footprint_kind, length, width, centre, yaw_rad)
    place_field = f"{field}.{'station_m' if spec.station_m is not None else 'xy_m'}"
    rows, cols, gx, gy = _window(heightfield, outline, place_field)
    ground = heightfield.height_at(np.vstack([outline, centre[None]]))
    base_z = float(np.min(ground))

    heights = heightfield.heights_m
    if spec.kind == "mound":
        a, b = _local(gx, gy, centre, yaw_rad)
        rho = np.sqrt((a / (0.5 * length)) ** 2 + (b / (0.5 * width)) ** 2)
        bump = height * 0.5 * (1.0 + np.cos(np.pi * np.clip(rho, 0.0, 1.0)))
        heights = heights.copy()
        heights[rows, cols] = (heights[rows, cols] + bump).astype(heights.dtype)
        base_z = float(heightfield.height_at(centre[None])[0])

    if spec.kind == "pedestrian":
        shape = "cylinder"
        half = np.array([0.5 * length, 0.5 * length, 0.5 * height])
    else:
        shape = "box"
        half = np.array([0.5 * width, 0.5 * length, 0.5 * height])  # body X right, Y forward
    record = PositiveObstacle(
        obstacle_id=obstacle_id,
        kind=spec.kind,  # type: ignore[arg-type]
        shape=shape,  # type: ignore[arg-type]
        centre_m=np.array([centre[0], centre[1], base_z + 0.5 * height]),
        half_extents_m=half,
        yaw_rad=float(yaw_rad),
        in_heightfield=spec.kind == "mound",
    )
    return HeightField(heights, heightfield.resolution_m, heightfield.origin_m), record
