"""ROI casting: cast only the rays of a native-resolution rig that can return a point the detectors read.

The detectors read the returns inside a vehicle-frame region (the observation grid's extent) and,
for the features of those returns, their neighbours in the range image (paper N §3.1: max filter,
5-neighbourhood edges, bump sides, density window, the A/C search on the lasers below/above). A
ray is cast when

1. its straight path within the sensor's range meets the box ``region x [z_lo, z_hi]`` in the
   vehicle frame, where ``[z_lo, z_hi]`` bounds every surface in the region (terrain and static
   bodies, from the world's physics heightfield and body AABBs, at the current true pose), so any
   ray whose first hit lies in the region is in this set; or
2. it lies within ``laser_margin`` lasers and ``column_margin`` columns of such a ray in the range
   image (the features' neighbourhoods; columns wrap around a 360 deg sensor's seam).

Per laser this is an azimuth window; lasers whose cone cannot reach the region are skipped. Masks
depend only on the rig, the region and the quantised height band, so they are computed once per
band and cached. The scan keeps the native shape: rays not cast are NaN (no return), rays cast
carry exactly the native scan's ranges, noise included (counter-based noise keyed per ray, see
:func:`~negobs_gym.sensors.noise.apply_keyed_noise`).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import maximum_filter

from negobs_gym.core.pose import Pose
from negobs_gym.errors import require
from negobs_gym.sensors.lidar import directions_vehicle
from negobs_gym.sensors.rigs import Rig, SensorMount

if TYPE_CHECKING:
    from negobs_gym.sim.world import World

__all__ = ["HeightEnvelope", "RaySubset", "RoiConfig", "RoiSelector"]


@dataclass(frozen=True, kw_only=True)
class RoiConfig:
    """Which rays of a rig ROI casting keeps.

    Attributes:
        region_xy_m: Vehicle-frame box ``(x_min, x_max, y_min, y_max)`` the detectors read [m]
            (the env uses its observation grid's extent).
        laser_margin: Lasers either side of a region ray also cast: paper N's density window (6
            lasers, ``Hdl64FeatureConfig.density_laser_window``) plus 2 for the A/C search across
            lasers with a missing return.
        column_margin: Columns either side also cast: max filter 3 + edge half-window 2 + bump
            side window 5 + density columns 2 (``Hdl64FeatureConfig``) + 4 spare; the HDL-32's
            same-laser density window (8) is inside it.
        height_step_m: Height bands are rounded outwards to multiples of this [m] and computed one
            step wider, so a few masks serve a whole drive (the papers are silent; 0.25 m: a
            finer step casts fewer rays but recomputes masks more often).
        full_sensors: Sensors always cast in full (paper T reads the whole LUX frame; it is small).
        cache_size: Masks kept (least recently used dropped first).
    """

    region_xy_m: tuple[float, float, float, float] = (-6.4, 6.4, -3.2, 25.6)
    laser_margin: int = 8
    column_margin: int = 16
    height_step_m: float = 0.25
    full_sensors: tuple[str, ...] = ("lux",)
    cache_size: int = 16

    def __post_init__(self) -> None:
        x0, x1, y0, y1 = (float(v) for v in self.region_xy_m)
        require(
            all(math.isfinite(v) for v in (x0, x1, y0, y1)) and x0 < x1 and y0 < y1,
            "region_xy_m",
            f"must be finite (x_min < x_max, y_min < y_max), got {self.region_xy_m}",
        )
        object.__setattr__(self, "region_xy_m", (x0, x1, y0, y1))
        for name in ("laser_margin", "column_margin"):
            v = getattr(self, name)
            require(isinstance(v, int) and v >= 0, name, f"must be an int >= 0, got {v!r}")
        require(math.isfinite(self.height_step_m) and self.height_step_m > 0, "height_step_m", "must be > 0")
        require(isinstance(self.cache_size, int) and self.cache_size >= 1, "cache_size", "must be >= 1")


@dataclass(frozen=True)
class RaySubset:
    """The rays of one sensor to cast: flat (laser-major) indices into its full direction table."""

    index: np.ndarray  # (k,) int32, increasing
    all_directions_vehicle: np.ndarray  # (lasers * columns, 3) unit vectors of the whole scan

    @property
    def size(self) -> int:
        """Number of rays."""
        return int(self.index.size)

    @property
    def directions_vehicle(self) -> np.ndarray:
        """(k, 3) vehicle-frame unit directions of the rays (gathered on use: masks stay small)."""
        return self.all_directions_vehicle[self.index]


def rays_meeting_box(
    origin: np.ndarray, directions: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_range_m: float
) -> np.ndarray:
    """Mask of rays ``origin + t d`` (0 <= t <= max_range_m) that meet the box [lo, hi] (slab test)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / directions
        t0 = (lo - origin) * inv
        t1 = (hi - origin) * inv
    # a zero direction component: inside the slab -> unbounded, outside -> empty
    zero = directions == 0.0
    inside = (origin >= lo) & (origin <= hi)
    t_near = np.where(zero, np.where(inside, -np.inf, np.inf), np.minimum(t0, t1))
    t_far = np.where(zero, np.where(inside, np.inf, -np.inf), np.maximum(t0, t1))
    enter = np.maximum(t_near.max(axis=1), 0.0)
    leave = np.minimum(t_far.min(axis=1), max_range_m)
    return enter <= leave


class HeightEnvelope:
    """Bounds of every surface the caster sees, per physics-heightfield sample (world frame).

    ``top`` is the terrain height raised to the AABB top of each static body over its footprint,
    ``bottom`` the terrain height lowered to each body's AABB bottom. :meth:`band` turns them into
    vehicle-frame bounds over a region at a pose, adding the current AABBs of the world's moving
    bodies (other vehicles) that are not excluded.
    """

    def __init__(self, world: World, exclude_body_ids: Iterable[int] = ()) -> None:
        import pybullet as p

        hf = world.physics_heightfield
        self.resolution_m = float(hf.resolution_m)
        self.origin_m = np.asarray(hf.origin_m, dtype=np.float64)
        h = np.asarray(hf.heights_m, dtype=np.float64)
        self.top = h.copy()
        self.bottom = h.copy()
        self._world = world
        self._exclude = {int(b) for b in exclude_body_ids}
        exclude = self._exclude | set(world.dynamic_body_ids())
        c = world.client_id
        for k in range(p.getNumBodies(physicsClientId=c)):
            body = p.getBodyUniqueId(k, physicsClientId=c)
            if body == world.terrain_body_id or body in exclude:
                continue
            for link in range(-1, p.getNumJoints(body, physicsClientId=c)):
                lo, hi = p.getAABB(body, link, physicsClientId=c)
                rows, cols = self._slice(lo[0], hi[0], lo[1], hi[1])
                self.top[rows, cols] = np.maximum(self.top[rows, cols], hi[2])
                self.bottom[rows, cols] = np.minimum(self.bottom[rows, cols], lo[2])

    def _slice(self, x0: float, x1: float, y0: float, y1: float) -> tuple[slice, slice]:
        """Sample rows/cols covering [x0, x1] x [y0, y1] plus the samples around it."""
        ny, nx = self.top.shape
        res = self.resolution_m
        i0 = int(np.clip(math.floor((x0 - self.origin_m[0]) / res), 0, nx - 1))
        i1 = int(np.clip(math.ceil((x1 - self.origin_m[0]) / res), 0, nx - 1))
        j0 = int(np.clip(math.floor((y0 - self.origin_m[1]) / res), 0, ny - 1))
        j1 = int(np.clip(math.ceil((y1 - self.origin_m[1]) / res), 0, ny - 1))
        return slice(j0, j1 + 1), slice(i0, i1 + 1)

    def band(self, pose: Pose, region_xy_m: tuple[float, float, float, float]) -> tuple[float, float]:
        """Vehicle-frame (z_min, z_max) of all surfaces over the region's footprint at ``pose``.

        Samples count whose vehicle-frame xy lies within the region grown by one sample spacing
        (a surface between samples is bounded by the samples around it); the height change of a
        tilted frame across one spacing is added. Outside the heightfield nothing is hit.
        """
        x0, x1, y0, y1 = region_xy_m
        res = self.resolution_m
        corners = pose.to_world(np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x0, y1, 0.0], [x1, y1, 0.0]]))
        lo, hi = corners.min(axis=0) - res, corners.max(axis=0) + res
        rows, cols = self._slice(lo[0], hi[0], lo[1], hi[1])
        rot = pose.rotation  # vehicle coordinates = rot.T @ (p - t)
        xs = self.origin_m[0] + res * np.arange(cols.start, cols.stop) - pose.x
        ys = self.origin_m[1] + res * np.arange(rows.start, rows.stop) - pose.y
        top = self.top[rows, cols] - pose.z
        bottom = self.bottom[rows, cols] - pose.z
        pad = res * 1.5
        vx = rot[0, 0] * xs[None, :] + rot[1, 0] * ys[:, None] + rot[2, 0] * bottom
        vy = rot[0, 1] * xs[None, :] + rot[1, 1] * ys[:, None] + rot[2, 1] * bottom
        inside = (vx >= x0 - pad) & (vx <= x1 + pad) & (vy >= y0 - pad) & (vy <= y1 + pad)
        if not inside.any():
            return 0.0, 0.0
        plane = rot[0, 2] * xs[None, :] + rot[1, 2] * ys[:, None]
        z_top = (plane + rot[2, 2] * top)[inside]
        z_bottom = (plane + rot[2, 2] * bottom)[inside]
        tilt = res * (abs(rot[0, 2]) + abs(rot[1, 2]))
        z_lo, z_hi = float(z_bottom.min()) - tilt, float(z_top.max()) + tilt
        for z in self._moving_z(pose):
            z_lo, z_hi = min(z_lo, z), max(z_hi, z)
        return z_lo, z_hi

    def _moving_z(self, pose: Pose) -> list[float]:
        """Vehicle-frame z of the AABB corners of the moving bodies not excluded."""
        import pybullet as p

        c = self._world.client_id
        out: list[float] = []
        for body in self._world.dynamic_body_ids():
            if body in self._exclude:
                continue
            for link in range(-1, p.getNumJoints(body, physicsClientId=c)):
                lo, hi = p.getAABB(body, link, physicsClientId=c)
                corners = np.array(np.meshgrid(*zip(lo, hi, strict=True))).reshape(3, -1).T
                out.extend(pose.to_vehicle(corners)[:, 2].tolist())
        return out


class RoiSelector:
    """Per-sensor ray subsets of a rig for a vehicle-frame region, cached by height band."""

    def __init__(self, rig: Rig, config: RoiConfig | None = None) -> None:
        self.rig = rig
        self.config = config if config is not None else RoiConfig()
        self._directions = {mt.name: directions_vehicle(mt) for mt in rig.mounts}
        self._full = {
            mt.name: RaySubset(
                np.arange(len(self._directions[mt.name]), dtype=np.int32), self._directions[mt.name]
            )
            for mt in rig.mounts
        }
        self._cache: OrderedDict[tuple[int, int], dict[str, RaySubset]] = OrderedDict()

    def band_key(self, z_min_m: float, z_max_m: float) -> tuple[int, int]:
        """The quantised height band (outward rounding) that covers [z_min_m, z_max_m]."""
        step = self.config.height_step_m
        return math.floor(z_min_m / step), math.ceil(z_max_m / step)

    def subsets(self, z_min_m: float, z_max_m: float) -> dict[str, RaySubset]:
        """Rays to cast per sensor when every surface in the region lies in [z_min_m, z_max_m].

        A cached band that contains the asked one serves it (its rays are a superset, so the scan
        inside the region is the same); otherwise a band one step wider each way is computed, so
        that small height changes along a drive keep hitting the cache.
        """
        lo, hi = self.band_key(z_min_m, z_max_m)
        for key in reversed(self._cache):  # most recently used first
            if key[0] <= lo and key[1] >= hi:
                self._cache.move_to_end(key)
                return self._cache[key]
        key = (lo - 1, hi + 1)
        step = self.config.height_step_m
        out = {mt.name: self._subset(mt, key[0] * step, key[1] * step) for mt in self.rig.mounts}
        self._cache[key] = out
        if len(self._cache) > self.config.cache_size:
            self._cache.popitem(last=False)
        return out

    def mask(self, mount: SensorMount, z_lo_m: float, z_hi_m: float) -> np.ndarray:
        """(lasers, columns) bool: the rays of ``mount`` cast for the height band [z_lo_m, z_hi_m]."""
        m = mount.model
        x0, x1, y0, y1 = self.config.region_xy_m
        meets = rays_meeting_box(
            np.asarray(mount.translation_m),
            self._directions[mount.name],
            np.array([x0, y0, z_lo_m]),
            np.array([x1, y1, z_hi_m]),
            m.max_range_m,
        ).reshape(m.n_lasers, m.n_columns)
        cfg = self.config
        size = (2 * cfg.laser_margin + 1, 2 * cfg.column_margin + 1)
        wrap = "wrap" if m.hfov_deg >= 360.0 else "constant"
        return maximum_filter(meets, size=size, mode=("constant", wrap), cval=False)

    def _subset(self, mount: SensorMount, z_lo_m: float, z_hi_m: float) -> RaySubset:
        if mount.name in self.config.full_sensors:
            return self._full[mount.name]
        index = np.flatnonzero(self.mask(mount, z_lo_m, z_hi_m)).astype(np.int32)
        return RaySubset(index, self._directions[mount.name])
