"""Region of interest of paper N's detector (Table 1, line 1: ``roi_points = ExtractROIPoints()``).

Paper N names the step but not its rule. The rule here: the feature tests may only use *ground*
returns inside the region the detector reports (within ``max_range_m``), so a pair is kept when

1. its A and its B lie on ground cells, not on cells holding vertical structure (walls, vehicle
   bodies, trunks, rocks, dense vegetation): the foot of a wall is a ground-level return in the same
   cell as the wall above it, and a wall's foot seen past the ground in front of it looks to Eq. 14
   like a pit's back wall;
2. no structure stands between A and B (B is not ground seen past an occluder: the "shadow" behind
   a parked car or a wall forms a range jump that Eq. 14 alone cannot tell from a pit);
3. C, the back-wall point beyond B, is not on structure either: a wall seen at a grazing angle puts
   B on the ground just before its foot and C on the wall. A real pit's C lies on its back wall or
   the ground beyond, at or below the rim's level, so it stays ground.

Ground vs structure comes from a polar elevation map around the vehicle origin, built from every
return of the frame (all sensors together): cells of ``sector_deg`` x ``bin_m``, each with its
lowest and highest point. Walking each sector outward from the vehicle (whose origin is on the
ground, z = 0), a cell's lowest point is ground when it lies within
``ground_step_m + tan(max_ground_slope_deg) * (distance to the last ground cell)`` above, or
``ground_step_m + tan(max_ground_slope_deg) * bin_m`` below, the last ground cell's level (then it
is the new ground level); a point is *structure* when it stands more than ``ground_tolerance_m`` above the
ground level of its cell. Drops are never structure, and a steep drop does not lower the ground
level: the back wall of a pit (and C beyond B, paper N Fig. 5) lies at or below the near rim's
level, so it stays ground, while anything rising above the ground in front of it is structure.

Cost: O(n): one compiled pass bins the points, a compiled walk per sector sets the ground levels.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from negobs_gym.core import libm
from negobs_gym.core.compiled import kernel
from negobs_gym.core.scan import StructuredScan
from negobs_gym.errors import require


@dataclass(frozen=True, kw_only=True)
class RoiConfig:
    """Constants of the ROI rule (paper N is silent on all of them; reasons given per field)."""

    enabled: bool = True  # False: every return counts as ground (the detector before the ROI step)
    # angular width of a polar cell: 0.5 deg is 17 cm at 20 m, under the 20 cm output grid cell
    sector_deg: float = 0.5
    # radial length of a polar cell: a quarter of the HDL-64 ring gap at 10 m, so a pit's near rim
    # and its back wall (>= w_min = 30 cm apart, Eq. 14) never share a cell
    bin_m: float = 0.25
    # height above the local ground that makes a return structure: above the 5-30 cm ground
    # bumps and ruts of an off-road track, below the 0.3 m of a rock or a kerb worth avoiding
    ground_tolerance_m: float = 0.25
    # steepest rise of the ground from one ground cell to the next: gentle terrain slopes
    # (<= ~10 % on off-road tracks) pass, a vehicle body or a wall (near vertical) does not
    max_ground_slope_deg: float = 12.0
    # step between neighbouring ground cells allowed on top of the slope: ruts, clods and range
    # noise (a few cm); smaller than ground_tolerance_m, so the ground level cannot climb a
    # rock's or a car's face cell by cell
    ground_step_m: float = 0.10
    # cells beyond the detector's max_range_m that still feed the map (the ground behind a pit
    # at the range limit is needed to judge it)
    range_margin_m: float = 2.0

    def __post_init__(self) -> None:
        require(isinstance(self.enabled, bool), "enabled", "must be a bool")
        require(
            math.isfinite(self.sector_deg) and 0 < self.sector_deg <= 45,
            "sector_deg",
            "must be in (0, 45]",
        )
        require(math.isfinite(self.bin_m) and self.bin_m > 0, "bin_m", "must be finite and > 0")
        require(
            math.isfinite(self.ground_tolerance_m) and self.ground_tolerance_m > 0,
            "ground_tolerance_m",
            "must be finite and > 0",
        )
        require(
            math.isfinite(self.ground_step_m) and 0 <= self.ground_step_m <= self.ground_tolerance_m,
            "ground_step_m",
            "must be in [0, ground_tolerance_m]",
        )
        require(
            math.isfinite(self.max_ground_slope_deg) and 0 <= self.max_ground_slope_deg < 90,
            "max_ground_slope_deg",
            "must be in [0, 90)",
        )
        require(
            math.isfinite(self.range_margin_m) and self.range_margin_m >= 0,
            "range_margin_m",
            "must be finite and >= 0",
        )


@dataclass(frozen=True, eq=False)
class GroundMap:
    """Polar elevation map of one frame (vehicle frame), see the module docstring.

    Attributes:
        ground_z_m: (sectors, bins) ground level of each cell [m].
        structure_before: (sectors, bins + 1) number of structure cells in bins ``< k`` of a sector.
        config: the rule's constants.
        n_bins: radial bins per sector.
        lowest_z_m: (sectors, bins) lowest return of each cell (inf: none), all sensors of the frame.
    """

    ground_z_m: np.ndarray
    structure_before: np.ndarray
    config: RoiConfig
    n_bins: int
    lowest_z_m: np.ndarray | None = None

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(sector, bin, inside) of (n, 2) vehicle-frame points."""
        n_sectors = self.ground_z_m.shape[0]
        sector = _xy_sectors(np.ascontiguousarray(xy), math.radians(self.config.sector_deg)) % n_sectors
        dist = np.hypot(xy[:, 0], xy[:, 1])
        b = np.floor(dist / self.config.bin_m).astype(np.int64)
        return sector, np.minimum(b, self.n_bins - 1), b < self.n_bins

    def is_structure(self, points_m: np.ndarray) -> np.ndarray:
        """(n,) True where a (n, 3) vehicle-frame point stands on vertical structure.

        Points beyond the map are judged against the last cell of their sector.
        """
        p = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        sector, b, _ = self.cells(p[:, :2])
        return p[:, 2] > self.ground_z_m[sector, b] + self.config.ground_tolerance_m

    def structure_between(
        self, a_m: np.ndarray, b_m: np.ndarray, c_m: np.ndarray | None = None
    ) -> np.ndarray:
        """(n,) True where a structure cell lies on B's sector from A's bin to one bin past B's (or
        past C's, where C is given and finite).

        Inclusive of B's and C's cells and the one beyond, since the foot of a wall or a vehicle
        body is a ground-level return in or next to the cell of the structure above it.
        """
        a = np.asarray(a_m, dtype=np.float64).reshape(-1, 3)
        b = np.asarray(b_m, dtype=np.float64).reshape(-1, 3)
        sector, bin_b, _ = self.cells(b[:, :2])
        _, bin_a, _ = self.cells(a[:, :2])
        far = np.maximum(bin_a, bin_b)
        if c_m is not None:
            c = np.asarray(c_m, dtype=np.float64).reshape(-1, 3)
            known = np.isfinite(c).all(axis=1)
            _, bin_c, _ = self.cells(np.where(known[:, None], c, b)[:, :2])
            far = np.maximum(far, bin_c)
        lo = np.minimum(bin_a, bin_b)
        hi = np.minimum(far + 2, self.n_bins)
        return self.structure_before[sector, hi] - self.structure_before[sector, lo] > 0

    def on_structure_cell(self, points_m: np.ndarray) -> np.ndarray:
        """(n,) True where a (n, 3) point lies in a cell that holds structure."""
        p = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        sector, b, _ = self.cells(p[:, :2])
        return self.structure_before[sector, b + 1] - self.structure_before[sector, b] > 0

    def keep_pairs(self, a_m: np.ndarray, b_m: np.ndarray, c_m: np.ndarray | None = None) -> np.ndarray:
        """(n,) True for pairs inside the ROI: A, B (and C) on ground cells, no structure between."""
        return ~(self.on_structure_cell(a_m) | self.structure_between(a_m, b_m, c_m))


# A ray's sector is trusted for its points when its angle lies farther than this (in sectors) from a
# sector boundary: far above the ~1e-13 sectors by which a point's rounded coordinates can move it.
_SECTOR_GUARD = 1e-9
_RAY_SECTORS: OrderedDict[tuple, np.ndarray] = OrderedDict()  # by scan geometry and sector width


def ray_sectors(scan: StructuredScan, config: RoiConfig) -> np.ndarray | None:
    """Ground-map sector of every ray of ``scan`` ((lasers, columns) ints), or None when the sector
    depends on the range.

    A sensor whose origin lies on the vehicle's z axis (translation x = y = 0, as the HDL-64 above
    the vehicle origin) sees every return of a ray at the ray's own vehicle-frame azimuth, whatever
    its range: the sector is computed once per scan geometry instead of once per point (the
    per-point ``arctan2`` was a quarter of the map's time); a deskewed scan's (``column_motion``)
    points are moved off their rays, so they take the per-point rule. Rays whose angle lies within
    :data:`_SECTOR_GUARD` of a sector boundary, or that point straight up or down, are -1: their
    points get the per-point rule, so the map is the same as without this table.
    """
    if scan.translation_m[0] != 0.0 or scan.translation_m[1] != 0.0 or scan.column_motion is not None:
        return None
    key = (
        scan.elevation_rad.tobytes(),
        scan.azimuth_rad.tobytes(),
        np.asarray(scan.rotation, dtype=np.float64).tobytes(),
        config.sector_deg,
    )
    table = _RAY_SECTORS.get(key)
    if table is None:
        x, y = scan.directions_vehicle[0], scan.directions_vehicle[1]  # the points' own directions
        where = _sector_position(x, y, math.radians(config.sector_deg))
        table = where.astype(np.int64)
        frac = where - table
        unsure = (frac < _SECTOR_GUARD) | (frac > 1.0 - _SECTOR_GUARD) | (x * x + y * y < 1e-20)
        table[unsure] = -1
        table.flags.writeable = False
        _RAY_SECTORS[key] = table
        if len(_RAY_SECTORS) > 16:
            _RAY_SECTORS.popitem(last=False)
    return table


def _sector_position(x: np.ndarray, y: np.ndarray, sector_rad: float) -> np.ndarray:
    """Angle of vehicle-frame directions or points from -pi, in sectors (>= 0)."""
    return (libm.arctan2(y, x) + np.pi) / sector_rad


def _point_sectors(p: np.ndarray, known: np.ndarray | None, sector_rad: float, reach_m: float) -> np.ndarray:
    """Sector (before wrapping) of every point of (n, 3) ``p`` that the map bins (finite, nearer than
    ``reach_m``): from ``known`` (per point, -1 = unknown) where given, else from its angle."""
    if known is None:
        sector, need = np.full(len(p), -1, dtype=np.int64), np.arange(len(p))
    else:
        sector, need = known, np.flatnonzero(known < 0)
        if need.size == 0:
            return sector
        sector = sector.copy()
    _angle_sectors(p, need, sector, sector_rad, reach_m * reach_m)
    return sector


# The per-point sector rule, floor((atan2(y, x) + pi) / sector), is compiled wherever a point's own
# sector is taken (binning the map, looking a point up), so both use the C library's atan2 on every
# machine, as the ray tables (:func:`ray_sectors`, through ``core.libm``) do. numpy's float64
# arctan2 is a SIMD routine on AVX-512 CPUs, which can differ in the last bit and so move a point
# lying within ~1e-15 of a sector boundary into the neighbour sector.


@kernel
def _exact_sector_of(x: float, y: float, sector_rad: float) -> int:
    """The per-point sector (before wrapping; >= 0, so truncation is the floor)."""
    return np.int64((np.arctan2(y, x) + np.pi) / sector_rad)


# atan(t) ~ t P(t^2) for |t| <= tan(pi / 8): least-squares fit on Chebyshev nodes, largest error
# 1.2e-10 rad on 2,000,001 samples of the interval (tests/detector/test_roi.py rechecks it)
_ATAN_COEFFS = (
    0.9999999961634439,
    -0.3333326985746865,
    0.1999698239021298,
    -0.14223617929650542,
    0.10477432329464499,
    -0.058310861060163637,
)
_TAN_PI_8 = math.tan(math.pi / 8)
# a polynomial angle farther than this from a sector boundary has the exact rule's sector: ~80x the
# polynomial's error (1.2e-10 rad) plus its rounding
_FAST_SECTOR_GUARD_RAD = 1e-8


@kernel
def _atan_small(t: float) -> float:
    w = t * t
    p = _ATAN_COEFFS[5]
    for c in (_ATAN_COEFFS[4], _ATAN_COEFFS[3], _ATAN_COEFFS[2], _ATAN_COEFFS[1], _ATAN_COEFFS[0]):
        p = p * w + c
    return t * p


@kernel
def _sector_of(x: float, y: float, sector_rad: float) -> int:
    """:func:`_exact_sector_of`, 1.6-1.8x faster on a frame's clouds: the angle from a polynomial, the exact
    rule (the C library's atan2) only where that lies within :data:`_FAST_SECTOR_GUARD_RAD` of a
    sector boundary, on an axis or at the origin (the HDL-32s' points take their sector one by
    one: this was a third of the ground map's time)."""
    ax, ay = abs(x), abs(y)
    big, small = max(ax, ay), min(ax, ay)
    if not (small > 0.0) or not np.isfinite(big):  # an axis (signed zeros), the origin, NaN, inf
        return _exact_sector_of(x, y, sector_rad)
    if small > _TAN_PI_8 * big:  # atan(s / b) = pi / 4 + atan((s - b) / (s + b))
        a = 0.25 * np.pi + _atan_small((small - big) / (small + big))
    else:
        a = _atan_small(small / big)
    if ay > ax:
        a = 0.5 * np.pi - a
    if x < 0.0:
        a = np.pi - a
    if y < 0.0:
        a = -a
    per_rad = 1.0 / sector_rad  # loop-invariant where this is inlined
    q = (a + np.pi) * per_rad
    frac, guard = q - np.floor(q), _FAST_SECTOR_GUARD_RAD * per_rad
    if frac < guard or frac > 1.0 - guard:
        return _exact_sector_of(x, y, sector_rad)
    return np.int64(q)


@kernel
def _angle_sectors(
    p: np.ndarray, rows: np.ndarray, sector: np.ndarray, sector_rad: float, reach2: float
) -> None:
    """The per-point sector of the ``rows`` of ``p`` nearer than the reach with a finite z (NaN
    compares False); the others keep their sector."""
    for k in range(rows.size):
        i = rows[k]
        x, y = p[i, 0], p[i, 1]
        if x * x + y * y < reach2 and np.isfinite(p[i, 2]):
            sector[i] = _sector_of(x, y, sector_rad)


@kernel
def _xy_sectors(xy: np.ndarray, sector_rad: float) -> np.ndarray:
    """The per-point sector of (n, 2) finite points."""
    sector = np.empty(xy.shape[0], dtype=np.int64)
    for i in range(xy.shape[0]):
        sector[i] = _sector_of(xy[i, 0], xy[i, 1], sector_rad)
    return sector


@kernel
def _bin_extremes(
    p: np.ndarray,
    sector: np.ndarray,
    reach2: float,
    bin_m: float,
    n_bins: int,
    n_sectors: int,
    z_min: np.ndarray,
    z_max: np.ndarray,
) -> None:
    """Lowest and highest z per polar cell (``z_min``, ``z_max``, flat, updated in place) of the
    finite points of (n, 3) ``p`` nearer than sqrt(``reach2``), in their ``sector`` (compiled: one
    pass over ~400,000 points a frame, where numpy needed a dozen, docs/detector_features.md)."""
    for k in range(p.shape[0]):
        x, y, z = p[k, 0], p[k, 1], p[k, 2]
        d2 = x * x + y * y
        if not (d2 < reach2) or not np.isfinite(z):  # NaN (no return) compares False
            continue
        radial = min(int(np.sqrt(d2) / bin_m), n_bins - 1)
        cell = (sector[k] % n_sectors) * n_bins + radial
        z_min[cell] = min(z_min[cell], z)
        z_max[cell] = max(z_max[cell], z)


@kernel
def _ground_levels(z_min: np.ndarray, bin_m: float, slope: float, step: float, fall: float) -> np.ndarray:
    """(sectors, bins) ground level of each cell: each sector walked outward from the vehicle origin
    (on the ground, z = 0) by the rule of the module docstring, on the cells' lowest points."""
    n_sectors, n_bins = z_min.shape
    ground = np.empty((n_sectors, n_bins))
    for s in range(n_sectors):
        z_g, d_g = 0.0, 0.0
        for k in range(n_bins):
            d_k = (k + 0.5) * bin_m
            low = z_min[s, k]
            # down: one cell's worth of slope only, so the back wall seen past a pit's shadow (empty
            # cells) is a drop, never the new ground level; an empty cell (inf) is not ground
            if np.isfinite(low) and low <= z_g + step + slope * (d_k - d_g) and low >= z_g - step - fall:
                z_g, d_g = low, d_k
            ground[s, k] = z_g
    return ground


def build_ground_map(
    clouds: Iterable[np.ndarray],
    max_range_m: float,
    config: RoiConfig,
    sectors: Sequence[np.ndarray | None] | None = None,
) -> GroundMap:
    """Polar elevation map from vehicle-frame clouds (any shape (..., 3), NaN rows = no return).

    ``sectors`` (optional, one per cloud: None, or each point's sector as :func:`ray_sectors` gives
    it, -1 = unknown) spares the per-point angle where it is known beforehand; the map is the same.
    """
    clouds = list(clouds)
    known_sectors = [None] * len(clouds) if sectors is None else list(sectors)
    require(len(known_sectors) == len(clouds), "sectors", "needs one entry (or None) per cloud")
    n_sectors = math.ceil(360.0 / config.sector_deg)
    n_bins = max(1, math.ceil((max_range_m + config.range_margin_m) / config.bin_m))
    n_cells = n_sectors * n_bins
    reach = n_bins * config.bin_m
    z_min = np.full(n_cells, np.inf)
    z_max = np.full(n_cells, -np.inf)
    sector_rad = math.radians(config.sector_deg)
    for cloud, known in zip(clouds, known_sectors, strict=True):
        p = np.ascontiguousarray(np.asarray(cloud, dtype=np.float64).reshape(-1, 3))
        known_flat = None if known is None else np.asarray(known, dtype=np.int64).reshape(-1)
        require(
            known_flat is None or known_flat.size == len(p),
            "sectors",
            "each table needs one sector per point of its cloud",
        )
        sector = _point_sectors(p, known_flat, sector_rad, reach)
        _bin_extremes(p, sector, reach * reach, config.bin_m, n_bins, n_sectors, z_min, z_max)
    z_min = z_min.reshape(n_sectors, n_bins)
    z_max = z_max.reshape(n_sectors, n_bins)

    slope = math.tan(math.radians(config.max_ground_slope_deg))
    fall = slope * config.bin_m
    tol = config.ground_tolerance_m
    step = config.ground_step_m
    ground = _ground_levels(z_min, config.bin_m, slope, step, fall)
    structure = z_max > ground + tol
    before = np.zeros((n_sectors, n_bins + 1), dtype=np.int64)
    np.cumsum(structure, axis=1, out=before[:, 1:])
    return GroundMap(ground, before, config, n_bins, z_min)
