"""Analytic structured scans for tests and benchmarks: a flat plane z = 0 (vehicle frame) with
axis-aligned rectangular holes of given depth and axis-aligned blocks standing on it (walls, box
cars, poles: vertical structure), seen by a sensor at a known mounting.

Rays are intersected with the plane and, where the plane hit falls inside a hole's opening,
with the inside of the hole (walls and floor, slab method); rays entering a block stop on it
(slab method) - fully vectorized. Two rig shapes:
an upright HDL-64-like sensor and a side HDL-32-like sensor rolled 90 deg about the vehicle Y
axis so that each laser (row) sweeps a vertical plane: its columns run from the nadir forward
(and backward), i.e. along one laser the ground hits go near -> far in the front half of the
spin (see :func:`hdl32_side_rotation`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan, ray_directions
from negobs_gym.errors import ConfigError, require

HDL64_ELEVATION_DEG = np.linspace(-24.8, 2.0, 64)  # HDL-64E-like, ~0.43 deg spacing
HDL32_ELEVATION_DEG = np.linspace(-30.67, 10.67, 32)  # HDL-32E, 1.33 deg spacing


def _check_box(box: object, size_field: str) -> None:
    """Finite footprint [x0, x1] x [y0, y1] with x1 > x0, y1 > y0, and a positive ``size_field``."""
    for name in ("x0_m", "x1_m", "y0_m", "y1_m", size_field):
        require(np.isfinite(getattr(box, name)), name, "must be finite")
    require(box.x1_m > box.x0_m, "x1_m", "must exceed x0_m")  # type: ignore[attr-defined]
    require(box.y1_m > box.y0_m, "y1_m", "must exceed y0_m")  # type: ignore[attr-defined]
    require(getattr(box, size_field) > 0, size_field, "must be > 0")


@dataclass(frozen=True, kw_only=True)
class Hole:
    """Axis-aligned rectangular hole in the vehicle frame: opening [x0, x1] x [y0, y1], depth."""

    x0_m: float
    x1_m: float
    y0_m: float
    y1_m: float
    depth_m: float

    def __post_init__(self) -> None:
        _check_box(self, "depth_m")

    @classmethod
    def ahead(cls, distance_m: float, width_m: float, length_m: float, depth_m: float) -> Hole:
        """Hole centred on x = 0 whose near rim is ``distance_m`` ahead (+Y) of the origin."""
        return cls(
            x0_m=-width_m / 2,
            x1_m=width_m / 2,
            y0_m=distance_m,
            y1_m=distance_m + length_m,
            depth_m=depth_m,
        )


@dataclass(frozen=True, kw_only=True)
class Block:
    """Axis-aligned block standing on the plane: footprint [x0, x1] x [y0, y1], top at ``height_m``."""

    x0_m: float
    x1_m: float
    y0_m: float
    y1_m: float
    height_m: float

    def __post_init__(self) -> None:
        _check_box(self, "height_m")


def _block_entry(o: np.ndarray, d: np.ndarray, block: Block) -> np.ndarray:
    """Ray parameter where unit rays ``o + t d`` enter ``block`` (inf = miss), slab method."""
    lo = np.array([block.x0_m, block.y0_m, 0.0])
    hi = np.array([block.x1_m, block.y1_m, block.height_m])
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t0 = (lo - o) * inv
        t1 = (hi - o) * inv
    t_near = np.nanmax(np.minimum(t0, t1), axis=-1)
    t_far = np.nanmin(np.maximum(t0, t1), axis=-1)
    return np.where((t_near <= t_far) & (t_far > 0), np.maximum(t_near, 0.0), np.inf)


def hdl32_side_rotation(side: str) -> np.ndarray:
    """Sensor-to-vehicle rotation of a side HDL-32 rolled 90 deg about the vehicle Y axis.

    ``"left"``: spin axis (sensor +Z) = vehicle -X, sensor +Y = vehicle +Y, sensor +X = up, so the
    nadir is at azimuth -90 deg and azimuths -90 -> 0 deg sweep the ground near -> far ahead.
    ``"right"``: sensor +Z = vehicle +X, sensor +X = down (nadir at azimuth +90 deg).
    """
    if side == "left":
        return np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    if side == "right":
        return np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    raise ConfigError("side", f"must be 'left' or 'right', got {side!r}")


def cast_ranges(
    origin_m: np.ndarray,
    directions: np.ndarray,
    holes: Sequence[Hole] = (),
    max_range_m: float = 120.0,
    blocks: Sequence[Block] = (),
) -> np.ndarray:
    """Ranges of unit rays from ``origin_m`` (vehicle frame) to the holed plane and the blocks on it;
    NaN = no hit."""
    o = np.asarray(origin_m, dtype=np.float64).reshape(3)
    d = np.asarray(directions, dtype=np.float64)
    require(o[2] > 0, "origin_m", "sensor must be above the plane z = 0")
    dz = d[..., 2]
    down = dz < -1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(down, -o[2] / np.where(down, dz, -1.0), np.nan)
        px = o[0] + t * d[..., 0]
        py = o[1] + t * d[..., 1]
        for hole in holes:
            inside = down & (px > hole.x0_m) & (px < hole.x1_m) & (py > hole.y0_m) & (py < hole.y1_m)
            if not inside.any():
                continue
            dx, dy = d[..., 0], d[..., 1]
            tx = np.where(dx > 0, (hole.x1_m - o[0]) / dx, (hole.x0_m - o[0]) / dx)
            ty = np.where(dy > 0, (hole.y1_m - o[1]) / dy, (hole.y0_m - o[1]) / dy)
            tz = (-hole.depth_m - o[2]) / dz
            tx = np.where(dx == 0, np.inf, tx)
            ty = np.where(dy == 0, np.inf, ty)
            t_exit = np.minimum(np.minimum(tx, ty), tz)
            t = np.where(inside, t_exit, t)
        for block in blocks:
            t = np.fmin(t, _block_entry(o, d, block))
    return np.where(t <= max_range_m, t, np.nan)


def synthetic_scan(
    sensor: str,
    elevation_rad: np.ndarray,
    azimuth_rad: np.ndarray,
    rotation: np.ndarray,
    translation_m: np.ndarray,
    holes: Sequence[Hole] = (),
    *,
    blocks: Sequence[Block] = (),
    max_range_m: float = 120.0,
    noise_sigma_m: float = 0.0,
    rng: np.random.Generator | None = None,
    pose: Pose | None = None,
) -> StructuredScan:
    """Structured scan of the holed plane; optional Gaussian range noise from ``rng``."""
    require(noise_sigma_m >= 0 and np.isfinite(noise_sigma_m), "noise_sigma_m", "must be >= 0")
    rot = np.asarray(rotation, dtype=np.float64)
    dirs = ray_directions(elevation_rad, azimuth_rad) @ rot.T
    ranges = cast_ranges(translation_m, dirs, holes, max_range_m, blocks)
    if noise_sigma_m > 0:
        require(rng is not None, "rng", "a np.random.Generator is needed when noise_sigma_m > 0")
        ranges = np.abs(ranges + rng.normal(0.0, noise_sigma_m, ranges.shape))
    return StructuredScan(
        sensor=sensor,
        ranges_m=ranges,
        azimuth_rad=azimuth_rad,
        elevation_rad=elevation_rad,
        rotation=rot,
        translation_m=np.asarray(translation_m, dtype=np.float64),
        pose=pose if pose is not None else Pose(),
    )


def hdl64_scan(
    holes: Sequence[Hole] = (),
    *,
    blocks: Sequence[Block] = (),
    height_m: float = 2.2,
    n_columns: int = 4000,
    elevation_deg: np.ndarray = HDL64_ELEVATION_DEG,
    noise_sigma_m: float = 0.0,
    rng: np.random.Generator | None = None,
) -> StructuredScan:
    """Upright HDL-64-like scan (sensor at (0, 0, height_m), R = I, full revolution)."""
    az = np.linspace(-np.pi, np.pi, n_columns, endpoint=False)
    return synthetic_scan(
        "hdl64",
        np.radians(np.sort(np.asarray(elevation_deg, dtype=np.float64))),
        az,
        np.eye(3),
        np.array([0.0, 0.0, height_m]),
        holes,
        blocks=blocks,
        noise_sigma_m=noise_sigma_m,
        rng=rng,
    )


def hdl32_side_scan(
    holes: Sequence[Hole] = (),
    *,
    blocks: Sequence[Block] = (),
    side: str = "left",
    height_m: float = 2.0,
    lateral_offset_m: float = 0.8,
    n_columns: int = 2250,
    elevation_deg: np.ndarray = HDL32_ELEVATION_DEG,
    noise_sigma_m: float = 0.0,
    rng: np.random.Generator | None = None,
) -> StructuredScan:
    """Side HDL-32-like scan, rolled 90 deg (see :func:`hdl32_side_rotation`).

    The sensor sits ``lateral_offset_m`` to the ``side`` of the vehicle centre line at
    ``height_m``; ``n_columns`` = 2250 gives the HDL-32E's 0.16 deg firing resolution.
    """
    x = -lateral_offset_m if side == "left" else lateral_offset_m
    az = np.linspace(-np.pi, np.pi, n_columns, endpoint=False)
    return synthetic_scan(
        f"hdl32_{side}",
        np.radians(np.sort(np.asarray(elevation_deg, dtype=np.float64))),
        az,
        hdl32_side_rotation(side),
        np.array([x, 0.0, height_m]),
        holes,
        blocks=blocks,
        noise_sigma_m=noise_sigma_m,
        rng=rng,
    )
