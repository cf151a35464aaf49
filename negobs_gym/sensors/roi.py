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

from negobs_gym.core.compiled import kernel
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, require
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
        rot = np.ascontiguousarray(pose.rotation, dtype=np.float64)  # vehicle = rot.T @ (p - t)
        xs = self.origin_m[0] + res * np.arange(cols.start, cols.stop) - pose.x
        ys = self.origin_m[1] + res * np.arange(rows.start, rows.stop) - pose.y
        top = self.top[rows, cols] - pose.z
        bottom = self.bottom[rows, cols] - pose.z
        found, z_low, z_high = _box_extremes(xs, ys, top, bottom, rot, np.ascontiguousarray(boxes), 1.5 * res)
        tilt = res * (abs(rot[0, 2]) + abs(rot[1, 2]))
        moving = self._moving_z(pose)
        out: list[tuple[float, float] | None] = []
        for k in range(len(boxes)):
            zs = list(moving)
            if found[k]:
                zs += [float(z_low[k]) - tilt, float(z_high[k]) + tilt]
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


@kernel
def _box_extremes(
    xs: np.ndarray,
    ys: np.ndarray,
    top: np.ndarray,
    bottom: np.ndarray,
    rot: np.ndarray,
    boxes: np.ndarray,
    pad: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per box (x_min, x_max, y_min, y_max, vehicle frame): whether a sample lies in it grown by
    ``pad`` (at its bottom or its top height), and the lowest bottom and highest top z of those
    samples. Samples: world offsets ``xs`` (columns) x ``ys`` (rows) from the pose, heights ``top``
    and ``bottom`` above it; vehicle coordinates ``(rot[0, i] x + rot[1, i] y) + rot[2, i] z``
    (one compiled pass where numpy made a dozen over the grid per box)."""
    n_b = boxes.shape[0]
    found = np.zeros(n_b, dtype=np.bool_)
    z_low = np.full(n_b, np.inf)
    z_high = np.full(n_b, -np.inf)
    lo_x, hi_x = boxes[:, 0] - pad, boxes[:, 1] + pad
    lo_y, hi_y = boxes[:, 2] - pad, boxes[:, 3] + pad
    for r in range(ys.size):
        for c in range(xs.size):
            vx_plane = rot[0, 0] * xs[c] + rot[1, 0] * ys[r]
            vy_plane = rot[0, 1] * xs[c] + rot[1, 1] * ys[r]
            plane = rot[0, 2] * xs[c] + rot[1, 2] * ys[r]
            b, t = bottom[r, c], top[r, c]
            vx_b, vx_t = vx_plane + rot[2, 0] * b, vx_plane + rot[2, 0] * t
            vy_b, vy_t = vy_plane + rot[2, 1] * b, vy_plane + rot[2, 1] * t
            z_b, z_t = plane + rot[2, 2] * b, plane + rot[2, 2] * t
            for k in range(n_b):
                if (lo_x[k] <= vx_b <= hi_x[k] and lo_y[k] <= vy_b <= hi_y[k]) or (
                    lo_x[k] <= vx_t <= hi_x[k] and lo_y[k] <= vy_t <= hi_y[k]
                ):
                    found[k] = True
                    z_low[k] = min(z_low[k], z_b)
                    z_high[k] = max(z_high[k], z_t)
    return found, z_low, z_high


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
            raise ConfigError("bands", f"need one band per tile ({len(self.tiles)}), got {len(bands)}")
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
            _mark_meeting(meets, rays.index, rays.z_min_m, rays.z_max_m, lo * step, hi * step)
        cfg = self.config
        return dilate(
            meets.reshape(m.n_lasers, m.n_columns), cfg.laser_margin, cfg.column_margin, m.hfov_deg >= 360.0
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


@kernel
def _mark_meeting(
    meets: np.ndarray, index: np.ndarray, z_min: np.ndarray, z_max: np.ndarray, lo: float, hi: float
) -> None:
    """In place: ``meets[index[k]] = True`` where ray k's z span [z_min, z_max] meets [lo, hi]."""
    for k in range(index.size):
        if z_min[k] <= hi and z_max[k] >= lo:
            meets[index[k]] = True


def dilate(mask: np.ndarray, laser_margin: int, column_margin: int, wrap_columns: bool) -> np.ndarray:
    """(lasers, columns) bool: True within ``laser_margin`` rows and ``column_margin`` columns of a
    True of ``mask``; columns wrap around (a 360 deg sensor's seam) where ``wrap_columns``, rows
    never. ``scipy.ndimage.maximum_filter`` of a (2 laser_margin + 1, 2 column_margin + 1) window
    with modes ("constant", "wrap" or "constant"), computed by two compiled running counts
    (tests/sensors/test_roi.py compares them)."""
    m = np.ascontiguousarray(mask, dtype=np.bool_)
    require(m.ndim == 2, "mask", f"must be (lasers, columns), got shape {m.shape}")
    require(laser_margin >= 0 and column_margin >= 0, "margins", "must be >= 0")
    return _dilated(m, int(laser_margin), int(column_margin), bool(wrap_columns))


@kernel
def _dilated(mask: np.ndarray, lm: int, cm: int, wrap: bool) -> np.ndarray:
    n_l, n_c = mask.shape
    rows = np.zeros((n_l, n_c), dtype=np.bool_)
    count = np.zeros(n_c + 1, dtype=np.int64)  # count[c] = Trues in columns < c of the row
    for laser in range(n_l):
        for c in range(n_c):
            count[c + 1] = count[c] + (1 if mask[laser, c] else 0)
        total = count[n_c]
        if total == 0:
            continue
        for c in range(n_c):
            lo, hi = c - cm, c + cm + 1  # window [lo, hi)
            if wrap and hi - lo >= n_c:
                rows[laser, c] = True
                continue
            inside = count[min(max(hi, 0), n_c)] - count[min(max(lo, 0), n_c)]
            if wrap:  # the parts of the window past either end, from the other end
                if lo < 0:
                    inside += total - count[n_c + lo]
                if hi > n_c:
                    inside += count[hi - n_c]
            rows[laser, c] = inside > 0
    out = np.zeros((n_l, n_c), dtype=np.bool_)
    run = np.zeros(n_c, dtype=np.int64)  # per column: Trues of ``rows`` in the laser window
    for laser in range(min(lm, n_l)):
        for c in range(n_c):
            run[c] += rows[laser, c]
    for laser in range(n_l):
        enter, leave = laser + lm, laser - lm - 1
        for c in range(n_c):
            if enter < n_l and rows[enter, c]:
                run[c] += 1
            if leave >= 0 and rows[leave, c]:
                run[c] -= 1
            out[laser, c] = run[c] > 0
    return out
