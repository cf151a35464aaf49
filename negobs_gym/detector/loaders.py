"""Loaders that turn recorded, unstructured LiDAR clouds into :class:`StructuredScan` range images.

Two inputs are supported:

* a cloud with a ring (laser) index per point, ``(x, y, z, intensity, ring)``;
* a cloud without ring index plus the sensor's elevation table, e.g. a KITTI-style float32
  ``x, y, z, intensity`` ``.bin`` file from an HDL-64E: the ring is recovered as the table entry
  nearest to each point's elevation.

Points are given in the sensor frame of this package (X right, Y forward, Z up) unless a loader
says otherwise; KITTI's velodyne frame (x forward, y left, z up) is converted by
:func:`load_kitti_bin`. Columns are azimuth bins of ``azimuth_resolution_deg`` over one revolution
(bin centres, azimuth clockwise from +Y); several points in one (ring, column) cell are resolved
deterministically by keeping the nearest. Rows are sorted by elevation, lowest first (detector
order). Using the bin centre and the table elevation as the ray moves a point by at most half a
bin in azimuth and by the ring's elevation spread; both are far below the detector's thresholds.
"""

from __future__ import annotations

import os

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.errors import ScanError

HDL64E_AZIMUTH_RESOLUTION_DEG = 0.09  # paper N §2.1, HDL-64 horizontal resolution


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
    n_cols = max(1, round(360.0 / azimuth_resolution_deg))
    res = 2 * np.pi / n_cols
    rng_m = np.linalg.norm(xyz, axis=1)
    keep = rng_m > 0
    xyz, ring, rng_m = xyz[keep], ring[keep].astype(np.int64), rng_m[keep]
    inten = None if intensity is None else np.asarray(intensity, dtype=np.float64).reshape(-1)
    if inten is not None:
        if inten.shape[0] != keep.size:
            raise ScanError(f"{sensor}: intensity must have one entry per point")
        inten = inten[keep]
    az = np.arctan2(xyz[:, 0], xyz[:, 1])  # clockwise from +Y
    col = np.clip(np.floor((az + np.pi) / res).astype(np.int64), 0, n_cols - 1)
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
        azimuth_rad=-np.pi + (np.arange(n_cols) + 0.5) * res,
        elevation_rad=el[order_rows],
        rotation=np.eye(3) if rotation is None else rotation,
        translation_m=np.zeros(3) if translation_m is None else translation_m,
        pose=pose if pose is not None else Pose(),
        timestamp_s=timestamp_s,
        intensity=inten_img,
    )


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
    e = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
    order = np.argsort(el)
    es = el[order]
    i = np.clip(np.searchsorted(es, e), 1, max(es.size - 1, 1))
    lo = np.maximum(i - 1, 0)
    hi = np.minimum(i, es.size - 1)
    pick = np.where(np.abs(e - es[lo]) <= np.abs(e - es[hi]), lo, hi)
    return order[pick]


def unstructured_to_scan(
    cloud: np.ndarray, elevation_rad: np.ndarray, *, sensor: str, **kwargs: object
) -> StructuredScan:
    """(N, 4) ``x, y, z, intensity`` sensor-frame cloud without ring -> structured scan."""
    p = _check_cloud(cloud, 4, sensor)
    rings = recover_rings(p[:, :3], elevation_rad)
    return cloud_to_scan(p[:, :3], rings, elevation_rad, sensor=sensor, intensity=p[:, 3], **kwargs)  # type: ignore[arg-type]


def load_kitti_bin(
    path: str | os.PathLike[str],
    elevation_rad: np.ndarray,
    *,
    sensor: str = "hdl64",
    **kwargs: object,
) -> StructuredScan:
    """Read a KITTI-style float32 ``x, y, z, intensity`` ``.bin`` (velodyne frame: x forward,
    y left, z up) and build a structured scan in this package's sensor frame (X right, Y forward)."""
    raw = np.fromfile(os.fspath(path), dtype=np.float32)
    if raw.size % 4:
        raise ScanError(f"{path}: size is not a multiple of 4 float32 values")
    kitti = raw.reshape(-1, 4).astype(np.float64)
    cloud = np.column_stack([-kitti[:, 1], kitti[:, 0], kitti[:, 2], kitti[:, 3]])
    return unstructured_to_scan(cloud, elevation_rad, sensor=sensor, **kwargs)
