"""ROI casting: cast only the rays of a native-resolution rig that can return a point the detectors read.

The detectors read the returns inside a vehicle-frame region (the observation grid's extent) and,
for the features of those returns, their neighbours in the range image (paper N §3.1: max filter,
5-neighbourhood edges, bump sides, density window, the A/C search on the lasers below/above). A
ray is cast when

1. its straight path within the sensor's range meets, over one tile of the region (the region is
   split into a few boxes), the tile's height band ``[z_lo, z_hi]`` in the vehicle frame, which
   bounds every surface over that tile (terrain and static bodies from the world's physics
   heightfield and body AABBs, other vehicles' AABBs, at the current true pose): any ray whose
   first hit lies in the region is in this set; or
2. it lies within ``laser_margin`` lasers and ``column_margin`` columns of such a ray in the range
   image (the features' neighbourhoods; columns wrap around a 360 deg sensor's seam).

Per laser this is an azimuth window; lasers whose cone cannot reach the region are skipped. Masks
depend only on the rig, the tiles and their quantised height bands, so they are computed once per
set of bands and cached. The scan keeps the native shape: rays not cast are NaN (no return), rays cast
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
        tiles: (across, along) split of the region into boxes with their own height band, so a
            tall obstacle or a crest in one part does not widen the band everywhere (papers
            silent; 4 x 4 = boxes of 3.2 m x 7.2 m on the envs' grid: 23 % fewer rays than one box on
            OffroadNav, finer splits gain < 2 % more).
        full_sensors: Sensors always cast in full (paper T reads the whole LUX frame; it is small).
        cache_size: Band sets whose masks are kept (least recently used dropped first), and
            the length of a caller's ``recent`` list (:meth:`RoiSelector.subsets_for_bands`).
    """

    region_xy_m: tuple[float, float, float, float] = (-6.4, 6.4, -3.2, 25.6)
    laser_margin: int = 8
    column_margin: int = 16
    height_step_m: float = 0.25
    tiles: tuple[int, int] = (4, 4)
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
        require(
            len(self.tiles) == 2 and all(isinstance(n, int) and 1 <= n <= 16 for n in self.tiles),
            "tiles",
            f"must be two ints in [1, 16], got {self.tiles!r}",
        )


@dataclass(frozen=True)
class RaySubset:
    """The rays of one sensor to cast: flat (laser-major) indices into its full direction table.

    ``columns`` is the half-open column span ``[start, stop)`` of the range image that holds every
    ray of the subset and ``RoiConfig.column_margin`` columns more either side (None: all
    columns). A scan cropped to it (``scan_rig(..., crop=True)``) gives the detectors the same
    features: their column windows reach at most ``column_margin`` columns and none wraps around
    the seam, so past the margin a crop's edge reads as the full image's columns of no return.
    """

    index: np.ndarray  # (k,) int32, increasing
    columns: tuple[int, int] | None = None

    @property
    def size(self) -> int:
        """Number of rays."""
        return int(self.index.size)


class HeightEnvelope:
    """Bounds of every surface the caster sees, per physics-heightfield sample (world frame).

    ``top`` is the terrain height raised to the AABB top of each static body over its footprint,
    ``bottom`` the terrain height lowered to each body's AABB bottom. :meth:`band` turns them into
    vehicle-frame bounds over a region at a pose, adding the current AABBs of the world's moving
    bodies (other vehicles) that are not excluded. It bounds the surfaces a caster sees when the
    caster's ground is the physics heightfield (``EmbreeConfig(ground="physics")``, the default
    and the envs', or the PyBullet backend); a caster on the terrain's finer grid can see heights
    between physics samples outside these bounds.
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
        """Vehicle-frame (z_min, z_max) of all surfaces over the region's footprint at ``pose``."""
        (band,) = self.bands(pose, [region_xy_m])
        return band if band is not None else (0.0, 0.0)

    def bands(
        self, pose: Pose, boxes_xy_m: list[tuple[float, float, float, float]]
    ) -> list[tuple[float, float] | None]:
        """Per vehicle-frame box, (z_min, z_max) of all surfaces over its footprint at ``pose``.

        Samples count whose vehicle-frame xy (at their bottom or top height) lies within the box
        grown by 1.5 sample spacings (a surface between samples is bounded by the samples around
        it); the height change of a tilted frame across one spacing is added. None: no surface
        (outside the heightfield, no moving body), nothing can be hit there.
        """
        res = self.resolution_m
        boxes = np.asarray(boxes_xy_m, dtype=np.float64).reshape(-1, 4)
        x0, x1 = boxes[:, 0].min(), boxes[:, 1].max()
        y0, y1 = boxes[:, 2].min(), boxes[:, 3].max()
        corners = pose.to_world(np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x0, y1, 0.0], [x1, y1, 0.0]]))
        lo, hi = corners.min(axis=0) - 2 * res, corners.max(axis=0) + 2 * res
        rows, cols = self._slice(lo[0], hi[0], lo[1], hi[1])
        rot = pose.rotation  # vehicle coordinates = rot.T @ (p - t)
        xs = (self.origin_m[0] + res * np.arange(cols.start, cols.stop) - pose.x)[None, :]
        ys = (self.origin_m[1] + res * np.arange(rows.start, rows.stop) - pose.y)[:, None]
        top = self.top[rows, cols] - pose.z
        bottom = self.bottom[rows, cols] - pose.z
        pad = 1.5 * res
        vx_plane, vy_plane = rot[0, 0] * xs + rot[1, 0] * ys, rot[0, 1] * xs + rot[1, 1] * ys
        vx = np.stack([vx_plane + rot[2, 0] * bottom, vx_plane + rot[2, 0] * top])
        vy = np.stack([vy_plane + rot[2, 1] * bottom, vy_plane + rot[2, 1] * top])
        plane = rot[0, 2] * xs + rot[1, 2] * ys
        z_top = plane + rot[2, 2] * top
        z_bottom = plane + rot[2, 2] * bottom
        tilt = res * (abs(rot[0, 2]) + abs(rot[1, 2]))
        moving = self._moving_z(pose)
        out: list[tuple[float, float] | None] = []
        for bx0, bx1, by0, by1 in boxes:
            inside = ((vx >= bx0 - pad) & (vx <= bx1 + pad) & (vy >= by0 - pad) & (vy <= by1 + pad)).any(0)
            zs = list(moving)
            if inside.any():
                zs += [float(z_bottom[inside].min()) - tilt, float(z_top[inside].max()) + tilt]
            out.append((min(zs), max(zs)) if zs else None)
        return out

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


_EMPTY = (10**9, -(10**9))  # band key of a tile with nothing to hit: contained in any band
#: Quantised (low, high) height band of every tile, in ``height_step_m`` units.
BandKey = tuple[tuple[int, int], ...]


@dataclass(frozen=True)
class _TileRays:
    """The rays of one sensor whose path crosses one tile's xy box, with their z range there."""

    index: np.ndarray  # (k,) int32
    z_min_m: np.ndarray  # (k,) lowest z of the ray over the tile [m]
    z_max_m: np.ndarray  # (k,) highest z of the ray over the tile [m]


def tile_rays(
    origin: np.ndarray,
    directions: np.ndarray,
    box_xy_m: tuple[float, float, float, float],
    max_range_m: float,
) -> _TileRays:
    """Rays ``origin + t d`` (0 <= t <= max_range_m) crossing the xy box, and their z span inside it."""
    x0, x1, y0, y1 = box_xy_m
    inf = np.full(len(directions), np.inf)
    t_near, t_far = np.zeros(len(directions)), np.full(len(directions), max_range_m)
    for axis, (lo, hi) in enumerate(((x0, x1), (y0, y1))):
        d = directions[:, axis]
        o = origin[axis]
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (lo - o) / d, (hi - o) / d
        parallel = d == 0.0
        inside = lo <= o <= hi
        near = np.where(parallel, np.where(inside, -inf, inf), np.minimum(t0, t1))
        far = np.where(parallel, np.where(inside, inf, -inf), np.maximum(t0, t1))
        t_near, t_far = np.maximum(t_near, near), np.minimum(t_far, far)
    hit = np.flatnonzero(t_near <= t_far)
    z_a = origin[2] + t_near[hit] * directions[hit, 2]
    z_b = origin[2] + t_far[hit] * directions[hit, 2]
    return _TileRays(hit.astype(np.int32), np.minimum(z_a, z_b), np.maximum(z_a, z_b))


class RoiSelector:
    """Per-sensor ray subsets of a rig for a vehicle-frame region, cached by the tiles' height bands.

    The region is split into ``RoiConfig.tiles`` boxes; a ray is selected when, over some tile,
    its z span meets that tile's height band. Each tile's rays and z spans are computed once, so a
    new set of bands costs a comparison per (ray, tile), the dilation and the gather.
    """

    def __init__(self, rig: Rig, config: RoiConfig | None = None) -> None:
        self.rig = rig
        self.config = config if config is not None else RoiConfig()
        self._directions = {mt.name: directions_vehicle(mt) for mt in rig.mounts}
        self._full = {
            mt.name: RaySubset(np.arange(len(self._directions[mt.name]), dtype=np.int32)) for mt in rig.mounts
        }
        self.tiles = self._tile_boxes()
        self._tile_rays = {
            mt.name: [
                tile_rays(np.asarray(mt.translation_m), self._directions[mt.name], box, mt.model.max_range_m)
                for box in self.tiles
            ]
            for mt in rig.mounts
            if mt.name not in self.config.full_sensors
        }
        self._cache: OrderedDict[BandKey, dict[str, RaySubset]] = OrderedDict()

    def _tile_boxes(self) -> list[tuple[float, float, float, float]]:
        x0, x1, y0, y1 = self.config.region_xy_m
        nx, ny = self.config.tiles
        xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
        return [
            (float(xs[i]), float(xs[i + 1]), float(ys[j]), float(ys[j + 1]))
            for j in range(ny)
            for i in range(nx)
        ]

    def band_key(self, band: tuple[float, float] | None) -> tuple[int, int]:
        """The quantised height band (outward rounding) covering ``band``; None = nothing to hit."""
        if band is None:
            return _EMPTY
        step = self.config.height_step_m
        return math.floor(band[0] / step), math.ceil(band[1] / step)

    def subsets(
        self, z_min_m: float, z_max_m: float, recent: list[BandKey] | None = None
    ) -> dict[str, RaySubset]:
        """Rays to cast per sensor when every surface in the region lies in [z_min_m, z_max_m]."""
        return self.subsets_for_bands([(z_min_m, z_max_m)] * len(self.tiles), recent)

    def subsets_for_bands(
        self, bands: list[tuple[float, float] | None], recent: list[BandKey] | None = None
    ) -> dict[str, RaySubset]:
        """Rays to cast per sensor given each tile's height band (see :meth:`HeightEnvelope.bands`).

        ``recent`` is the caller's own list of the band sets it cast with (most recent last; this
        call updates it). A recent set that contains the asked bands tile by tile serves them (its
        rays are a superset, so the scan inside the region is the same); otherwise the bands one
        step wider each way are cast, so that small height changes along a drive keep hitting.
        Which rays are cast is then a function of the caller's own bands only: one list per
        episode makes an episode's scans independent of what else ran in the process (the masks
        themselves are kept, LRU, across callers). Without ``recent`` every call casts the
        widened asked bands.
        """
        if len(bands) != len(self.tiles):
            raise ValueError(f"need one band per tile ({len(self.tiles)}), got {len(bands)}")
        asked = [self.band_key(b) for b in bands]
        history = recent if recent is not None else []
        for i in range(len(history) - 1, -1, -1):  # most recently used first
            key = history[i]
            if all(c[0] <= a[0] and c[1] >= a[1] for c, a in zip(key, asked, strict=True)):
                history.append(history.pop(i))
                return self._masks_for(key)
        key = tuple(a if a == _EMPTY else (a[0] - 1, a[1] + 1) for a in asked)
        history.append(key)
        del history[: -self.config.cache_size]
        return self._masks_for(key)

    def _masks_for(self, key: BandKey) -> dict[str, RaySubset]:
        out = self._cache.get(key)
        if out is None:
            out = {mt.name: self._subset(mt, key) for mt in self.rig.mounts}
            self._cache[key] = out
            if len(self._cache) > self.config.cache_size:
                self._cache.popitem(last=False)
        else:
            self._cache.move_to_end(key)
        return out

    def mask(self, mount: SensorMount, key: BandKey) -> np.ndarray:
        """(lasers, columns) bool: the rays of ``mount`` cast for the tiles' quantised bands."""
        m = mount.model
        step = self.config.height_step_m
        meets = np.zeros(m.n_lasers * m.n_columns, dtype=bool)
        for rays, (lo, hi) in zip(self._tile_rays[mount.name], key, strict=True):
            if (lo, hi) == _EMPTY:
                continue
            sel = (rays.z_min_m <= hi * step) & (rays.z_max_m >= lo * step)
            meets[rays.index[sel]] = True
        cfg = self.config
        size = (2 * cfg.laser_margin + 1, 2 * cfg.column_margin + 1)
        wrap = "wrap" if m.hfov_deg >= 360.0 else "constant"
        return maximum_filter(
            meets.reshape(m.n_lasers, m.n_columns), size=size, mode=("constant", wrap), cval=False
        )

    def _subset(self, mount: SensorMount, key: BandKey) -> RaySubset:
        if mount.name in self.config.full_sensors:
            return self._full[mount.name]
        mask = self.mask(mount, key)
        index = np.flatnonzero(mask).astype(np.int32)
        cast = np.flatnonzero(mask.any(axis=0))
        if cast.size == 0:
            return RaySubset(index, (0, 0))
        pad = self.config.column_margin
        return RaySubset(index, (max(0, int(cast[0]) - pad), min(mask.shape[1], int(cast[-1]) + 1 + pad)))
