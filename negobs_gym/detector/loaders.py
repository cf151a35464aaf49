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
  the nearest entry of an elevation table only when the order is not that firing order. The
  table is one unit's calibration; another unit's lasers sit up to a few tenths of a degree
  elsewhere, about the HDL-64E's laser spacing, so the table mis-assigns rings that the order
  gets right. :class:`RingAssignment` says which was used.

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
from negobs_gym.errors import ScanError

HDL64E_AZIMUTH_RESOLUTION_DEG = 0.09  # paper N §2.1, HDL-64 horizontal resolution
# A laser's sweep never steps back in azimuth by more than this between consecutive points
# (per-laser azimuth offsets and jitter are below 1 deg); a larger step against the spin starts the
# next laser. The paper is silent (it reads structured scans); 20 deg separates the two cases by
# an order of magnitude on both sides.
RING_WRAP_STEP_RAD = np.radians(20.0)

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


def measured_ring_elevations(xyz_m: np.ndarray, ring: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Compact ring ids ``0..k-1`` (in the order of the original ids) and each ring's median elevation.

    The median of a whole ring is its laser's elevation seen from the sensor origin; single points
    near the sensor deviate by the laser's offset from the origin, the median does not.
    """
    ids, compact = np.unique(np.asarray(ring), return_inverse=True)
    el = point_elevation(np.asarray(xyz_m, dtype=np.float64))
    order = np.lexsort((el, compact))
    counts = np.bincount(compact, minlength=ids.size)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    sorted_el = el[order]
    lo = sorted_el[starts + (counts - 1) // 2]
    hi = sorted_el[starts + counts // 2]
    return compact.reshape(-1), 0.5 * (lo + hi)


def rings_from_point_order(xyz_m: np.ndarray, elevation_rad: np.ndarray) -> np.ndarray | None:
    """Ring index of each point of a cloud stored laser by laser, or None if it is not.

    Within one laser the azimuth runs one way around (the spin direction, taken from the median
    step) and each laser's sweep starts over at the same azimuth (KITTI: behind the car). The next
    laser therefore starts where the azimuth steps back against the spin by more than
    ``RING_WRAP_STEP_RAD`` (through the +-180 deg seam or not). Neighbouring pieces whose median
    elevations differ by less than half the table's median laser spacing are one laser cut at the
    seam and are joined. The order is accepted when it yields 2..len(``elevation_rad``) rings with
    distinct elevations whose spread within a ring (median absolute deviation) is below the table's
    laser spacing; any other order (azimuth-major firing blocks, shuffled, merged clouds) -> None.
    """
    xyz = np.asarray(xyz_m, dtype=np.float64)
    table = np.sort(np.asarray(elevation_rad, dtype=np.float64).reshape(-1))
    if xyz.shape[0] < 2 or table.size < 2:
        return None
    table_spacing = float(np.median(np.diff(table)))
    az = libm.arctan2(xyz[:, 0], xyz[:, 1])
    step = np.diff(az)
    inside = step[np.abs(step) < np.pi]  # steps across the +-180 deg seam say nothing about direction
    if inside.size == 0 or np.median(inside) == 0:
        return None
    spin = np.sign(np.median(inside))
    back = spin * step < -RING_WRAP_STEP_RAD
    # A laser whose sweep starts a little before the +-180 deg seam is cut there: the piece after the
    # seam ends before the piece before it starts (in spin order). Such cuts are joined.
    cut = np.flatnonzero(back) + 1  # first point of each new piece
    if cut.size:
        a = spin * az
        starts = np.concatenate([[0], cut])
        ends = np.concatenate([cut - 1, [xyz.shape[0] - 1]])
        across_seam = np.abs(step[cut - 1]) > np.pi
        joined = across_seam & (a[ends[1:]] < a[starts[:-1]])
        back[cut[joined] - 1] = False
    ring = np.concatenate([[0], np.cumsum(back)])
    el = point_elevation(xyz)
    n_rings = int(ring[-1]) + 1
    if not 2 <= n_rings <= table.size:
        return None
    compact, med = measured_ring_elevations(xyz, ring)
    if (np.diff(np.sort(med)) <= 0).any():
        return None
    dev = np.abs(el - med[compact])
    mad = np.array([np.median(d) for d in np.split(dev, np.flatnonzero(np.diff(ring)) + 1)])
    if np.median(mad) >= table_spacing:
        return None
    return ring


def assign_rings(xyz_m: np.ndarray, elevation_rad: np.ndarray) -> RingAssignment:
    """Rings of a cloud without ring field: from the point order if it is laser by laser, else from
    the elevation table (nearest entry). ``elevation_rad`` also bounds the number of rings."""
    xyz = np.asarray(xyz_m, dtype=np.float64)
    table = np.asarray(elevation_rad, dtype=np.float64).reshape(-1)
    if table.size == 0:
        raise ScanError("elevation table is empty")
    ring = rings_from_point_order(xyz, table)
    if ring is not None:
        compact, el = measured_ring_elevations(xyz, ring)
        return RingAssignment(compact, el, "point_order")
    return RingAssignment(recover_rings(xyz, table), table, "elevation_table")


def unstructured_to_scan(
    cloud: np.ndarray, elevation_rad: np.ndarray, *, sensor: str, **kwargs: object
) -> StructuredScan:
    """(N, 4) ``x, y, z, intensity`` sensor-frame cloud without ring -> structured scan.

    Rings come from :func:`assign_rings` (point order first, elevation table as fallback); which
    one was used is logged at INFO. Use :func:`assign_rings` directly to get it as a value.
    """
    p = _check_cloud(cloud, 4, sensor)
    rings = assign_rings(p[:, :3], elevation_rad)
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

    Rings: see :func:`unstructured_to_scan`."""
    kitti = read_float32_cloud(path, 4)
    cloud = np.column_stack([ros_to_sensor_frame(kitti[:, :3]), kitti[:, 3]])
    return unstructured_to_scan(cloud, elevation_rad, sensor=f"{sensor}", **kwargs)


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
