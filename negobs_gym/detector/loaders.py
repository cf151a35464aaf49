"""Loaders that turn recorded, unstructured LiDAR clouds into :class:`StructuredScan` range images.

numpy only (the file formats that need third-party readers live in :mod:`negobs_gym.detector.io`).
Inputs:

* a cloud with a ring (laser) index per point, ``(x, y, z, intensity, ring)``: with the sensor's
  elevation table (:func:`ring_cloud_to_scan`) or with the ring elevations measured from the
  points themselves (:func:`measured_ring_cloud_to_scan`, any ring numbering, e.g. a VLP-32C's
  interleaved channel ids);
* a cloud without ring index, e.g. a KITTI-style float32 ``x, y, z, intensity`` ``.bin`` file:
  :func:`assign_rings` recovers the ring from the point order when the cloud is stored laser by
  laser (each laser's sweep in azimuth order, as KITTI's HDL-64E clouds are), and falls back to
  the nearest entry of an elevation table, with a warning naming the file, only when the order is
  not that firing order. The table is one unit's calibration; another unit's lasers sit up to a
  few tenths of a degree elsewhere, about the HDL-64E's laser spacing, so the table mis-assigns
  rings that the order gets right. :class:`RingAssignment` says which was used.

Points are given in the sensor frame of this package (X right, Y forward, Z up) unless a loader
says otherwise; the ROS / KITTI / Velodyne-driver frame (x forward, y left, z up) is converted by
:func:`ros_to_sensor_frame`. Columns are azimuth bins of ``azimuth_resolution_deg`` over one
revolution (bin centres, azimuth clockwise from +Y); several points in one (ring, column) cell are
resolved deterministically by keeping the nearest. Rows are sorted by elevation, lowest first
(detector order). Using the bin centre and the row elevation as the ray moves a point by at most
half a bin in azimuth and by the ring's elevation spread; both are far below the detector's
thresholds.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from typing import Literal

import numpy as np

from negobs_gym.core import libm
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.errors import ScanError, require

HDL64E_AZIMUTH_RESOLUTION_DEG = 0.09  # paper N §2.1, HDL-64 horizontal resolution


@dataclass(frozen=True)
class PointOrderConfig:
    """Thresholds of the ring recovery from a laser-by-laser point order (:func:`rings_from_point_order`).

    The papers are silent (they read structured scans); the values fit KITTI's HDL-64E layout (0.18
    deg between a laser's points, 0.3-0.5 deg between lasers) and per-laser azimuth offsets of a few
    degrees.
    """

    # Within one laser the azimuth, counted from the sweep's origin, never drops by more than this
    # (jitter and parallax of the laser's offset from the axis are below 1 deg); a larger drop starts
    # the next laser. A drop through the origin itself is a full turn.
    back_step_deg: float = 20.0
    # Spacing of a grid of candidate origins (the azimuth where every laser's sweep starts: KITTI's
    # front, a driver's +-180 deg seam), besides every return a laser spacing off its neighbour in
    # elevation; the one whose cuts best fit the elevation steps between neighbouring returns wins
    # (see neighbour_gap_deg, min_cut_step_spacings).
    origin_step_deg: float = 10.0
    # Returns at most this far apart in azimuth are neighbours: their elevation step tells two lasers
    # from one (a few dropped returns at KITTI's 0.18 deg spacing). A cloud whose consecutive points
    # are mostly farther apart is not stored in sweep order.
    neighbour_gap_deg: float = 2.0
    # How far a laser's first point may lie from the chosen origin (per-laser azimuth offsets, a
    # laser cut at the seam): each boundary moves, inside this window, to a step back against the
    # spin (see jitter_deg) if there is one.
    boundary_window_deg: float = 10.0
    # The order is accepted if neighbouring points of two lasers step in elevation by at least this
    # many of the elevation table's median laser spacings (median over the lasers' starts) ...
    min_cut_step_spacings: float = 0.5
    # ... and neighbouring points of one laser by at most this many (median over all points).
    max_laser_step_spacings: float = 0.25
    # Steps back against the spin up to this are jitter within a laser (KITTI: 0.02 deg); a larger
    # one near a laser's start is where it begins (see boundary_window_deg).
    jitter_deg: float = 0.05
    # A cut across which the elevation steps no more than within a laser (max_laser_step_spacings)
    # is no laser start: it moves, within this, to the largest elevation step if that reaches
    # min_cut_step_spacings (a laser starting a few points off the origin, e.g. across the seam).
    near_window_deg: float = 1.0
    # A step back larger than this is no laser starting before the previous one ended (their offsets
    # from the origin, each within boundary_window_deg, differ by at most twice it) but a gap in a
    # cropped sweep: velodyne_reduced's +-45 deg view jumps 270 deg forward, read as 90 deg back.
    max_offset_step_deg: float = 20.0

    def __post_init__(self) -> None:
        require(0.0 < self.back_step_deg < 180.0, "back_step_deg", "must be in (0, 180)")
        require(0.0 < self.origin_step_deg <= 180.0, "origin_step_deg", "must be in (0, 180]")
        require(0.0 <= self.boundary_window_deg < 180.0, "boundary_window_deg", "must be in [0, 180)")
        require(self.jitter_deg >= 0.0, "jitter_deg", "must be >= 0")
        require(
            0.0 <= self.near_window_deg <= self.boundary_window_deg,
            "near_window_deg",
            "must be in [0, boundary_window_deg]",
        )
        require(self.min_cut_step_spacings > 0.0, "min_cut_step_spacings", "must be > 0")
        require(self.max_laser_step_spacings > 0.0, "max_laser_step_spacings", "must be > 0")
        require(self.neighbour_gap_deg > 0.0, "neighbour_gap_deg", "must be > 0")
        require(
            self.jitter_deg < self.max_offset_step_deg < 180.0,
            "max_offset_step_deg",
            "must be in (jitter_deg, 180)",
        )


log = logging.getLogger(__name__)


def _check_cloud(points: np.ndarray, n_fields: int, name: str) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] < n_fields:
        raise ScanError(f"{name}: cloud must have shape (N, >= {n_fields}), got {p.shape}")
    if not np.isfinite(p[:, :n_fields]).all():
        raise ScanError(f"{name}: cloud contains NaN or inf values")
    return p


def cloud_to_scan(
    xyz_m: np.ndarray,
    ring: np.ndarray,
    elevation_rad: np.ndarray,
    *,
    sensor: str,
    intensity: np.ndarray | None = None,
    azimuth_resolution_deg: float = HDL64E_AZIMUTH_RESOLUTION_DEG,
    rotation: np.ndarray | None = None,
    translation_m: np.ndarray | None = None,
    pose: Pose | None = None,
    timestamp_s: float = 0.0,
    columns_centred: bool = False,
    crop_columns: bool = False,
) -> StructuredScan:
    """Bin a sensor-frame cloud with known ring indices into a structured scan.

    Args:
        xyz_m: (N, 3) points in the sensor frame [m].
        ring: (N,) integer laser index into ``elevation_rad``.
        elevation_rad: (lasers,) elevation of each ring [rad].
        sensor: Sensor name of the scan.
        intensity: Optional (N,) intensities.
        azimuth_resolution_deg: Column width [deg]; must divide into at least one column.
        rotation, translation_m, pose, timestamp_s: Passed to :class:`StructuredScan`.
        columns_centred: Centre the columns on multiples of the width (see :func:`azimuth_columns`).
        crop_columns: Keep only the columns from the first to the last that holds a return (see
            :func:`column_span`): a scanner whose field of view is narrower than a revolution
            gets a range image of its own width (the LUX's 110 deg: 441 of 1,440 columns).

    Raises:
        ScanError: non-finite points, rings outside the table, bad resolution, shape mismatch.
    """
    xyz = _check_cloud(xyz_m, 3, sensor)[:, :3]
    el = np.asarray(elevation_rad, dtype=np.float64).reshape(-1)
    ring = np.asarray(ring)
    if ring.shape != (xyz.shape[0],):
        raise ScanError(f"{sensor}: ring must have one entry per point, got {ring.shape}")
    if ring.size and (np.any(ring != np.round(ring)) or ring.min() < 0 or ring.max() >= el.size):
        raise ScanError(f"{sensor}: ring indices must be integers in [0, {el.size})")
    if not (np.isfinite(azimuth_resolution_deg) and 0 < azimuth_resolution_deg <= 360):
        raise ScanError(f"{sensor}: azimuth_resolution_deg must be in (0, 360]")
    rng_m = np.linalg.norm(xyz, axis=1)
    keep = rng_m > 0
    xyz, ring, rng_m = xyz[keep], ring[keep].astype(np.int64), rng_m[keep]
    inten = None if intensity is None else np.asarray(intensity, dtype=np.float64).reshape(-1)
    if inten is not None:
        if inten.shape[0] != keep.size:
            raise ScanError(f"{sensor}: intensity must have one entry per point")
        inten = inten[keep]
    col, n_cols = azimuth_columns(xyz, azimuth_resolution_deg, centred=columns_centred)
    azimuth = -np.pi + (np.arange(n_cols) + (0.0 if columns_centred else 0.5)) * (2 * np.pi / n_cols)
    if crop_columns:
        first, stop = column_span(col, n_cols)
        col, n_cols, azimuth = col - first, stop - first, azimuth[first:stop]
    order_rows = np.argsort(el, kind="stable")
    row_of_ring = np.empty(el.size, dtype=np.int64)
    row_of_ring[order_rows] = np.arange(el.size)
    row = row_of_ring[ring]
    cell = row * n_cols + col
    # nearest point per cell wins; ties broken by input order (stable sort)
    srt = np.lexsort((np.arange(cell.size), rng_m, cell))
    cell_s = cell[srt]
    first = np.ones(cell_s.size, dtype=bool)
    first[1:] = cell_s[1:] != cell_s[:-1]
    sel = srt[first]
    ranges = np.full(el.size * n_cols, np.nan)
    ranges[cell[sel]] = rng_m[sel]
    inten_img = None
    if inten is not None:
        inten_img = np.full(el.size * n_cols, np.nan)
        inten_img[cell[sel]] = inten[sel]
        inten_img = inten_img.reshape(el.size, n_cols)
    return StructuredScan(
        sensor=sensor,
        ranges_m=ranges.reshape(el.size, n_cols),
        azimuth_rad=azimuth,
        elevation_rad=el[order_rows],
        rotation=np.eye(3) if rotation is None else rotation,
        translation_m=np.zeros(3) if translation_m is None else translation_m,
        pose=pose if pose is not None else Pose(),
        timestamp_s=timestamp_s,
        intensity=inten_img,
    )


def azimuth_columns(
    xyz_m: np.ndarray, azimuth_resolution_deg: float, *, centred: bool = False
) -> tuple[np.ndarray, int]:
    """The range-image column of each sensor-frame point (azimuth clockwise from +Y) and the number
    of columns, as :func:`cloud_to_scan` bins them.

    Column 0 starts at -180 deg; with ``centred`` it is centred there instead, so every column is
    centred on a multiple of the width. A spinning sensor's firing azimuths drift over a revolution
    and fall anywhere in a column; a fixed-angle scanner (IBEO LUX, SICK LD-MRS) fires at multiples
    of its resolution, which would lie on the column edges, where a coordinate's last bit decides
    the side and two neighbouring returns can share a column.
    """
    n_cols = max(1, round(360.0 / azimuth_resolution_deg))
    az = libm.arctan2(xyz_m[:, 0], xyz_m[:, 1])
    width = 2 * np.pi / n_cols
    if centred:
        return np.floor((az + np.pi) / width + 0.5).astype(np.int64) % n_cols, n_cols
    return np.clip(np.floor((az + np.pi) / width).astype(np.int64), 0, n_cols - 1), n_cols


def column_span(col: np.ndarray, n_cols: int) -> tuple[int, int]:
    """``(first, stop)``: the columns from the first to the last of ``col`` (the range-image column
    of each return), the whole ``n_cols`` when there is none. The span does not wrap around the
    revolution's seam at -180 deg, so a scanner facing backwards keeps most of its columns."""
    if col.size == 0:
        return 0, n_cols
    return int(col.min()), int(col.max()) + 1


def ring_cloud_to_scan(
    cloud: np.ndarray, elevation_rad: np.ndarray, *, sensor: str, **kwargs: object
) -> StructuredScan:
    """(N, 5) ``x, y, z, intensity, ring`` sensor-frame cloud -> structured scan."""
    p = _check_cloud(cloud, 5, sensor)
    return cloud_to_scan(p[:, :3], p[:, 4], elevation_rad, sensor=sensor, intensity=p[:, 3], **kwargs)  # type: ignore[arg-type]


def recover_rings(xyz_m: np.ndarray, elevation_rad: np.ndarray) -> np.ndarray:
    """Ring index of each point: the elevation-table entry nearest to the point's elevation."""
    xyz = np.asarray(xyz_m, dtype=np.float64)
    el = np.asarray(elevation_rad, dtype=np.float64).reshape(-1)
    if el.size == 0:
        raise ScanError("elevation table is empty")
    e = libm.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
    order = np.argsort(el)
    es = el[order]
    i = np.clip(np.searchsorted(es, e), 1, max(es.size - 1, 1))
    lo = np.maximum(i - 1, 0)
    hi = np.minimum(i, es.size - 1)
    pick = np.where(np.abs(e - es[lo]) <= np.abs(e - es[hi]), lo, hi)
    return order[pick]


RingSource = Literal["point_order", "elevation_table", "ring_field"]


@dataclass(frozen=True, eq=False)
class RingAssignment:
    """Ring of each point of a cloud and where it came from.

    Attributes:
        ring: (N,) ring index of each point, into ``elevation_rad``.
        elevation_rad: (rings,) elevation of each ring [rad].
        source: ``"point_order"`` (azimuth wrap-arounds of a laser-by-laser cloud, elevations
            measured from the points), ``"elevation_table"`` (nearest table entry) or
            ``"ring_field"`` (read from the file, elevations measured from the points).
    """

    ring: np.ndarray
    elevation_rad: np.ndarray
    source: RingSource


def point_elevation(xyz_m: np.ndarray) -> np.ndarray:
    """Elevation of each point above the sensor's XY plane [rad]."""
    return libm.arctan2(xyz_m[:, 2], np.hypot(xyz_m[:, 0], xyz_m[:, 1]))


def measured_ring_elevations(
    xyz_m: np.ndarray, ring: np.ndarray, point_elevation_rad: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Compact ring ids ``0..k-1`` (in the order of the original ids) and each ring's median elevation.

    The median of a whole ring is its laser's elevation seen from the sensor origin; single points
    near the sensor deviate by the laser's offset from the origin, the median does not.
    ``point_elevation_rad``: the points' :func:`point_elevation` where the caller has it.
    """
    ids, compact = np.unique(np.asarray(ring), return_inverse=True)
    el = (
        point_elevation(np.asarray(xyz_m, dtype=np.float64))
        if point_elevation_rad is None
        else np.asarray(point_elevation_rad, dtype=np.float64)
    )
    order = np.lexsort((el, compact))
    counts = np.bincount(compact, minlength=ids.size)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    sorted_el = el[order]
    lo = sorted_el[starts + (counts - 1) // 2]
    hi = sorted_el[starts + counts // 2]
    return compact.reshape(-1), 0.5 * (lo + hi)


def _pieces(a_rad: np.ndarray, origin_rad: float, back_step_rad: float) -> np.ndarray:
    """Start flags of the lasers of a sweep-ordered cloud, cut at ``origin_rad``: a point starts a
    laser where its azimuth (spin-wise, ``a_rad``), counted from the origin in [0, 2 pi), drops by
    more than ``back_step_rad`` from the point before."""
    u = np.mod(a_rad - origin_rad, 2 * np.pi)
    start = np.zeros(a_rad.size, dtype=bool)
    start[1:] = np.diff(u) < -back_step_rad
    return start


def _origin_scores(
    b_rad: np.ndarray,
    el: np.ndarray,
    origins: np.ndarray,
    back_step_rad: float,
    gap_rad: float,
    min_step: float,
) -> np.ndarray:
    """How well the cuts of each of the sorted ``origins`` (:func:`_pieces`) fit the elevation: +1 for
    each cut between neighbouring returns (at most ``gap_rad`` apart in azimuth) whose elevation
    steps by ``min_step`` or more (two lasers), -1 for each such cut that steps less (one laser cut
    in two). Neighbouring returns of one laser lie at nearly one elevation whatever their range;
    returns far apart in azimuth say nothing and do not count.

    With ``b_rad`` the spin-wise azimuth in [0, 2 pi), origin ``o`` cuts before point i + 1 where
    ``b`` passes it going forward (``b[i] < o <= b[i + 1]``, a step short of a full turn) and where
    ``b`` drops by more than ``back_step_rad`` without passing it going back (not ``b[i + 1] < o <=
    b[i]``). Each condition holds for a run of the sorted origins, so all scores come from one pass.
    """
    b = b_rad
    db = np.diff(b)
    near = np.abs(np.mod(db + np.pi, 2 * np.pi) - np.pi) <= gap_rad
    vote = np.where(np.abs(np.diff(el)) >= min_step, 1, -1) * near
    n = origins.size

    def added(low: np.ndarray, high: np.ndarray, value: np.ndarray) -> np.ndarray:
        """``value`` summed onto the origins in (low, high], as differences along ``origins``."""
        lo = np.searchsorted(origins, low, side="right")
        hi = np.searchsorted(origins, high, side="right")  # one past the last origin <= high
        ok = lo < hi
        return np.bincount(lo[ok], value[ok], n + 1) - np.bincount(hi[ok], value[ok], n + 1)

    big = db < -back_step_rad
    ahead = (db > 0) & (db < 2 * np.pi - back_step_rad)
    acc = added(b[1:][big], b[:-1][big], -vote[big]) + added(b[:-1][ahead], b[1:][ahead], vote[ahead])
    return np.sum(vote[big]) + np.cumsum(acc)[:n]


def _refine(
    forward: np.ndarray,
    el: np.ndarray,
    start: np.ndarray,
    window: int,
    near: int,
    jitter: float,
    min_step: float,
    laser_step: float,
    max_back: float,
) -> np.ndarray:
    """Move each laser start within reach of where it was cut (halfway to its neighbours at most).

    Within ``window`` points: to the point after the largest step back against the spin, if one
    exceeds ``jitter``; within a laser the azimuth never steps back, so such a step is where the
    next laser's sweep begins before the previous one's ended (per-laser azimuth offsets). A step
    back beyond ``max_back`` is a cropped sweep's gap, a jump forward, and is passed over. Else,
    where the elevation steps by no more than ``laser_step`` across the cut (as between returns of
    one laser: a laser starts a few points off the origin), within ``near`` points: to the largest
    elevation step, if that reaches ``min_step``. ``forward`` holds each azimuth step with the spin.
    """
    cuts = np.flatnonzero(start)
    if cuts.size == 0:
        return start
    d_el = np.abs(np.diff(el))
    bounds = np.concatenate([[0], cuts, [el.size]])
    refined = cuts.copy()
    for j, cut in enumerate(cuts):
        first = max((bounds[j] + cut + 1) // 2, 1)
        last = (cut + bounds[j + 2]) // 2
        lo, hi = max(cut - window, first), min(cut + window, last)
        steps = forward[lo - 1 : hi - 1]  # the step into point i is forward[i - 1]
        steps = np.where(steps < -max_back, 0.0, steps)
        if steps.size and steps.min() < -jitter:
            refined[j] = lo + int(np.argmin(steps))
        elif d_el[cut - 1] <= laser_step:
            lo, hi = max(cut - near, first), min(cut + near + 1, last)
            jumps = d_el[lo - 1 : hi - 1]
            if jumps.size and jumps.max() >= min_step:
                refined[j] = lo + int(np.argmax(jumps))
    out = np.zeros(start.size, dtype=bool)
    out[refined] = True
    return out


def _point_order_rings(
    xyz: np.ndarray, table: np.ndarray, config: PointOrderConfig
) -> tuple[tuple[np.ndarray, np.ndarray] | None, str]:
    """((ring of each point, each ring's median elevation), "") for a laser-by-laser cloud, else
    (None, why not)."""
    if xyz.shape[0] < 2 or table.size < 2:
        return None, "fewer than 2 points or table entries"
    table_spacing = float(np.median(np.diff(table)))
    az = libm.arctan2(xyz[:, 0], xyz[:, 1])
    step = np.mod(np.diff(az) + np.pi, 2 * np.pi) - np.pi  # shortest way round, across the seam too
    if np.median(step) == 0:
        return None, "the azimuth does not sweep"
    if np.median(np.abs(step)) > np.radians(config.neighbour_gap_deg):
        return None, "consecutive points are mostly far apart in azimuth"
    spin = np.sign(np.median(step))
    a = spin * az  # the sweep runs towards larger a
    el = point_elevation(xyz)
    back = np.radians(config.back_step_deg)
    min_step = config.min_cut_step_spacings * table_spacing
    # candidate origins: a grid, and every return that follows a neighbour a laser spacing away in
    # elevation (where a laser may start)
    b = np.mod(a, 2 * np.pi)
    d_b = np.mod(np.diff(b) + np.pi, 2 * np.pi) - np.pi
    starts = (np.abs(d_b) <= np.radians(config.neighbour_gap_deg)) & (np.abs(np.diff(el)) >= min_step)
    grid = np.arange(0.0, 2 * np.pi, np.radians(config.origin_step_deg))
    origins = np.unique(np.concatenate([grid, b[1:][starts]]))
    scores = _origin_scores(b, el, origins, back, np.radians(config.neighbour_gap_deg), min_step)
    start = _pieces(a, float(origins[int(np.argmax(scores))]), back)
    n_rings = int(np.count_nonzero(start)) + 1  # moving the cuts below keeps their number
    if not 2 <= n_rings <= table.size:
        return None, f"{n_rings} lasers found, the table has {table.size}"
    forward = spin * step
    typical = float(np.median(forward[forward > 0])) if (forward > 0).any() else 0.0
    window = int(np.radians(config.boundary_window_deg) / typical) if typical > 0 else 0
    reach = int(np.radians(config.near_window_deg) / typical) if typical > 0 else 0
    laser_step_max = config.max_laser_step_spacings * table_spacing
    start = _refine(
        forward,
        el,
        start,
        window,
        reach,
        np.radians(config.jitter_deg),
        min_step,
        laser_step_max,
        np.radians(config.max_offset_step_deg),
    )
    ring = np.cumsum(start)
    d_el = np.abs(np.diff(el))
    across, within = d_el[start[1:]], d_el[~start[1:]]
    cut_step = float(np.median(across)) if across.size else 0.0
    laser_step = float(np.median(within)) if within.size else 0.0
    if cut_step < min_step:
        return None, (
            f"median elevation step between lasers {np.degrees(cut_step):.3f} deg, "
            f"at least {np.degrees(min_step):.3f} deg expected"
        )
    if laser_step > laser_step_max:
        return None, (
            f"median elevation step within lasers {np.degrees(laser_step):.3f} deg, "
            f"at most {np.degrees(laser_step_max):.3f} deg expected"
        )
    compact, med = measured_ring_elevations(xyz, ring, el)
    if (np.diff(np.sort(med)) <= 0).any():
        return None, "two lasers share an elevation"
    return (compact, med), ""


def rings_from_point_order(
    xyz_m: np.ndarray, elevation_rad: np.ndarray, config: PointOrderConfig | None = None
) -> np.ndarray | None:
    """Ring index of each point of a cloud stored laser by laser, or None if it is not.

    Within one laser the azimuth runs one way around (the spin direction, taken from the median step)
    over one turn, and every laser's sweep starts at about the same azimuth, the origin (KITTI's HDL-64E
    files: straight ahead; a driver cutting at the +-180 deg seam: behind). Counted from the origin, the
    azimuth therefore rises through a laser and drops where the next begins: by a full turn where the
    sweep is continuous (KITTI), by less where points are missing or a field of view is cropped. A drop
    of more than ``config.back_step_deg`` starts a laser. The origin is the candidate (a grid every
    ``config.origin_step_deg`` and every return that follows a neighbour a laser spacing away in
    elevation) whose cuts best fit the elevation: neighbouring returns of one laser lie at nearly one
    elevation, those of two lasers a laser spacing apart (a laser's whole ring is no good measure: its
    returns' elevation seen from the sensor origin moves by a degree or more with their range, the laser
    sitting a few cm off it). Each laser's start then moves, within ``config.boundary_window_deg``, to a
    step back against the spin, where the next laser's sweep begins before the previous one's ended
    (per-laser azimuth offsets: a laser whose sweep starts before the origin has its points split at the
    start and the end of its ring; a step back beyond ``config.max_offset_step_deg`` is a cropped
    sweep's gap and does not count), or, where the cut steps too little in elevation, within
    ``config.near_window_deg`` to the largest elevation step. The order is accepted when it yields
    2..len(``elevation_rad``) lasers with distinct median elevations, neighbouring points of two lasers
    at least ``config.min_cut_step_spacings`` of the table's laser spacing apart in elevation and
    neighbouring points of one laser at most ``config.max_laser_step_spacings`` (medians); any other
    order (azimuth-major firing blocks, shuffled, merged clouds) -> None. Dropped points (no return) do
    not matter unless a whole turn of a laser between two lasers' returns is empty.
    """
    xyz = np.asarray(xyz_m, dtype=np.float64)
    table = np.sort(np.asarray(elevation_rad, dtype=np.float64).reshape(-1))
    rings, _ = _point_order_rings(xyz, table, config or PointOrderConfig())
    return None if rings is None else rings[0]


def assign_rings(
    xyz_m: np.ndarray,
    elevation_rad: np.ndarray,
    *,
    source: str | None = None,
    config: PointOrderConfig | None = None,
) -> RingAssignment:
    """Rings of a cloud without ring field: from the point order if it is laser by laser, else from
    the elevation table (nearest entry), with a warning naming ``source`` (the file) and why the
    order was refused. ``elevation_rad`` also bounds the number of rings."""
    xyz = np.asarray(xyz_m, dtype=np.float64)
    table = np.asarray(elevation_rad, dtype=np.float64).reshape(-1)
    if table.size == 0:
        raise ScanError("elevation table is empty")
    rings, why = _point_order_rings(xyz, np.sort(table), config or PointOrderConfig())
    if rings is not None:
        return RingAssignment(rings[0], rings[1], "point_order")
    log.warning(
        "%s: points are not stored laser by laser (%s); rings from the nearest elevation-table entry, "
        "which mis-rings points where this unit's lasers sit off the table; %s",
        source or "cloud without ring field",
        why,
        _table_fit(xyz, table),
    )
    return RingAssignment(recover_rings(xyz, table), table, "elevation_table")


def _table_fit(xyz: np.ndarray, table: np.ndarray) -> str:
    """How many points lie outside the table's elevation span, said so that a file that is no scan of
    this sensor (another sensor's, a tilted mount's, an image written as x, y, z points) shows."""
    if xyz.shape[0] == 0:
        return "no points"
    lo, hi = float(table.min()), float(table.max())
    el = point_elevation(xyz)
    outside = float(np.mean((el < lo) | (el > hi)))
    return (
        f"{100 * outside:.0f} % of the points lie outside the table's elevations "
        f"({np.degrees(lo):.1f} to {np.degrees(hi):.1f} deg; points from "
        f"{np.degrees(el.min()):.1f} to {np.degrees(el.max()):.1f} deg)"
    )


def unstructured_to_scan(
    cloud: np.ndarray,
    elevation_rad: np.ndarray,
    *,
    sensor: str,
    source: str | None = None,
    point_order: PointOrderConfig | None = None,
    **kwargs: object,
) -> StructuredScan:
    """(N, 4) ``x, y, z, intensity`` sensor-frame cloud without ring -> structured scan.

    Rings come from :func:`assign_rings` (point order first, with ``point_order``'s thresholds,
    elevation table as fallback, with a warning naming ``source``); which one was used is logged at
    INFO. Use :func:`assign_rings` directly to get it as a value.
    """
    p = _check_cloud(cloud, 4, sensor)
    rings = assign_rings(p[:, :3], elevation_rad, source=source or sensor, config=point_order)
    log.info("%s: rings from %s (%d rings)", sensor, rings.source, rings.elevation_rad.size)
    return cloud_to_scan(
        p[:, :3],
        rings.ring,
        rings.elevation_rad,
        sensor=sensor,
        intensity=p[:, 3],
        **kwargs,  # type: ignore[arg-type]
    )


def measured_ring_cloud_to_scan(
    xyz_m: np.ndarray, ring: np.ndarray, *, sensor: str, intensity: np.ndarray | None = None, **kwargs: object
) -> StructuredScan:
    """Sensor-frame cloud with a ring id per point (any numbering) -> structured scan, one row per
    ring present, each at the median elevation of its points (no calibration table needed)."""
    xyz = _check_cloud(xyz_m, 3, sensor)[:, :3]
    ring = np.asarray(ring).reshape(-1)
    if ring.shape[0] != xyz.shape[0]:
        raise ScanError(
            f"{sensor}: ring must have one entry per point, got {ring.shape[0]} for {xyz.shape[0]}"
        )
    if xyz.shape[0] == 0:
        raise ScanError(f"{sensor}: cloud has no points")
    if not np.isfinite(ring.astype(np.float64)).all():
        raise ScanError(f"{sensor}: ring field contains NaN or inf")
    compact, el = measured_ring_elevations(xyz, ring)
    return cloud_to_scan(xyz, compact, el, sensor=sensor, intensity=intensity, **kwargs)  # type: ignore[arg-type]


def ros_to_sensor_frame(xyz_m: np.ndarray) -> np.ndarray:
    """Points from the ROS / KITTI / Velodyne-driver frame (x forward, y left, z up) to this
    package's sensor frame (X right, Y forward, Z up)."""
    p = np.asarray(xyz_m, dtype=np.float64)
    return np.column_stack([-p[:, 1], p[:, 0], p[:, 2]])


def sensor_to_ros_frame(xyz_m: np.ndarray) -> np.ndarray:
    """Points from this package's sensor frame (X right, Y forward, Z up) to the ROS frame (x
    forward, y left, z up): the inverse of :func:`ros_to_sensor_frame`, to write a scan as a
    driver would publish it."""
    p = np.asarray(xyz_m)
    return np.column_stack([p[:, 1], -p[:, 0], p[:, 2]])


def read_float32_cloud(path: str | os.PathLike[str], n_fields: int) -> np.ndarray:
    """(N, n_fields) float64 array from a headerless float32 binary; ScanError if empty or truncated."""
    name = os.fspath(path)
    try:
        raw = np.fromfile(name, dtype=np.float32)
    except OSError as error:
        raise ScanError(f"{name}: cannot read ({error.strerror or error})") from error
    if raw.size == 0:
        raise ScanError(f"{name}: file is empty")
    if raw.size % n_fields:
        raise ScanError(
            f"{name}: size is not a multiple of {n_fields} float32 values "
            f"({n_fields} fields per point expected; truncated or another layout)"
        )
    return raw.reshape(-1, n_fields).astype(np.float64)


def load_kitti_bin(
    path: str | os.PathLike[str],
    elevation_rad: np.ndarray,
    *,
    sensor: str = "hdl64",
    **kwargs: object,
) -> StructuredScan:
    """Read a KITTI-style float32 ``x, y, z, intensity`` ``.bin`` (velodyne frame: x forward,
    y left, z up) and build a structured scan in this package's sensor frame (X right, Y forward).

    Rings: see :func:`unstructured_to_scan` (``point_order=`` its :class:`PointOrderConfig`)."""
    kitti = read_float32_cloud(path, 4)
    cloud = np.column_stack([ros_to_sensor_frame(kitti[:, :3]), kitti[:, 3]])
    return unstructured_to_scan(
        cloud,
        elevation_rad,
        sensor=f"{sensor}",
        source=os.fspath(path),
        **kwargs,  # type: ignore[arg-type]
    )


def load_ring_bin(path: str | os.PathLike[str], *, sensor: str = "hdl64", **kwargs: object) -> StructuredScan:
    """Read a float32 ``x, y, z, intensity, ring`` binary (velodyne frame: x forward, y left, z up);
    rows at the measured ring elevations (:func:`measured_ring_cloud_to_scan`)."""
    p = read_float32_cloud(path, 5)
    _check_cloud(p, 5, os.fspath(path))
    if np.any(p[:, 4] != np.round(p[:, 4])) or (p[:, 4] < 0).any():
        raise ScanError(f"{os.fspath(path)}: ring column must hold integers >= 0 (is it a KITTI xyzi file?)")
    return measured_ring_cloud_to_scan(
        ros_to_sensor_frame(p[:, :3]), p[:, 4].astype(np.int64), sensor=sensor, intensity=p[:, 3], **kwargs
    )
