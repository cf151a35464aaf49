"""Side HDL-32 negative-obstacle feature pairs (paper N §3.2).

Scan layout assumed (the side rig of :mod:`negobs_gym.detector.synthetic` and the sensors
package): the sensor is rolled 90 deg, so one row (laser) of the range image sweeps a vertical
plane and its columns cross the ground radially. "Along each laser near to far" is taken in
both column directions: at column ``k`` the sequence ``k-2, k-1, k`` (or ``k+2, k+1, k``) is
used where the flat-ground hit distances of those rays increase (a property of the ray
geometry alone, so it holds for any mounting). Pipeline: missing-return compensation ->
same-laser density (its threshold falling beyond ``density_full_range_m``) -> range jump
(second difference) -> pair (A = previous point,
B = jump point, C = next point beyond B's back-wall neighbourhood, see
``Hdl32FeatureConfig.c_min_separation_m``) -> Eq. 14.
"""

from __future__ import annotations

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.config import Hdl32FeatureConfig
from negobs_gym.detector.hdl64 import sensor_height
from negobs_gym.detector.pair_test import pair_test
from negobs_gym.detector.pairs import FeaturePairs


def ground_hit_distance(scan: StructuredScan, height_m: float) -> np.ndarray:
    """Horizontal distance from the sensor at which each ray would hit flat ground (inf = never)."""
    return _ray_tables(scan, height_m)[0].copy()


def _ray_tables(scan: StructuredScan, height_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ground-hit distances and the near-to-far masks of both walking directions (read-only),
    kept for the last few scan geometries and heights (a rig's sensor keeps its own from frame to
    frame; a recorded or moved one brings new ones)."""
    key = (scan.elevation_rad.tobytes(), scan.azimuth_rad.tobytes(), scan.rotation.tobytes(), float(height_m))
    tables = _RAY_TABLES.get(key)
    if tables is None:
        ground = height_m * _ground_hit_per_metre(scan.directions_vehicle)
        tables = (ground, _near_to_far(ground, 1), _near_to_far(ground, -1))
        for t in tables:
            t.flags.writeable = False
        if len(_RAY_TABLES) >= _MAX_RAY_TABLES:
            _RAY_TABLES.pop(next(iter(_RAY_TABLES)))
        _RAY_TABLES[key] = tables
    return tables


_RAY_TABLES: dict[tuple[bytes | float, ...], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
_MAX_RAY_TABLES = 8


def _ground_hit_per_metre(directions_vehicle: np.ndarray) -> np.ndarray:
    """Ground-hit distance per metre of sensor height of each ray, from the rays' vehicle-frame
    directions (3, lasers, columns), which the scan's points are built from too."""
    dx, dy, dz = directions_vehicle
    down = dz < -1e-9
    horiz = np.hypot(dx, dy)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(down, horiz / np.where(down, -dz, 1.0), np.inf)


def compensate_missing(ranges_m: np.ndarray) -> np.ndarray:
    """Fill a missing return from the neighbouring laser(s) at the same column (same emission
    angle of the sweep), only where the estimate lies between the row's neighbours (the range
    sequence is ordered there). Used only to judge range jumps, never as a detection."""
    r = np.ascontiguousarray(ranges_m, dtype=np.float64)
    n_l, n_c = r.shape
    if n_c < 3 or n_l < 2:
        return r.copy()
    return _compensated(r)


@kernel
def _compensated(r: np.ndarray) -> np.ndarray:
    """:func:`compensate_missing` of an image of at least 2 x 3: the estimate is the mean of the
    lasers above and below (the one there is, where the other has no return or does not exist),
    ordered when it lies within the NaN-skipping min and max of the row's left and right returns."""
    n_l, n_c = r.shape
    out = r.copy()
    for laser in range(n_l):
        for col in range(n_c):
            if not np.isnan(r[laser, col]):
                continue
            up = r[laser + 1, col] if laser + 1 < n_l else np.nan
            dn = r[laser - 1, col] if laser > 0 else np.nan
            est = dn if np.isnan(up) else (up if np.isnan(dn) else 0.5 * (up + dn))
            left = r[laser, col - 1] if col > 0 else np.nan
            right = r[laser, col + 1] if col + 1 < n_c else np.nan
            lo = right if np.isnan(left) else (left if np.isnan(right) else min(left, right))
            hi = right if np.isnan(left) else (left if np.isnan(right) else max(left, right))
            if est >= lo and est <= hi:  # NaN compares False
                out[laser, col] = est
    return out


def same_laser_density(
    points_m: np.ndarray,
    radius_m: float,
    half_window: int,
    rows: np.ndarray | None = None,
    cols: np.ndarray | None = None,
) -> np.ndarray:
    """Number of points of the same laser (own included) within ``radius_m`` of each point,
    searched over ``+-half_window`` columns; 0 for missing points.

    With ``rows``/``cols`` only those points are evaluated ((n,) result), else every point
    ((lasers, columns) result). Cost: O(points evaluated x half_window).
    """
    n_l, n_c, _ = points_m.shape
    if rows is None or cols is None:
        rr, cc = np.indices((n_l, n_c))
        return same_laser_density(points_m, radius_m, half_window, rr.ravel(), cc.ravel()).reshape(n_l, n_c)
    rows, cols = np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64)
    offs = np.concatenate([np.arange(-half_window, 0), np.arange(1, half_window + 1)])
    nb = cols[:, None] + offs[None, :]
    inside = (nb >= 0) & (nb < n_c)
    q = points_m[rows, cols]
    d = points_m[rows[:, None], np.clip(nb, 0, n_c - 1)] - q[:, None, :]
    with np.errstate(invalid="ignore"):
        near = inside & (np.einsum("nkd,nkd->nk", d, d) <= radius_m * radius_m)
    return np.where(np.isnan(q[:, 0]), 0.0, 1.0 + near.sum(axis=1))


def density_threshold(points_m: np.ndarray, sensor_m: np.ndarray, config: Hdl32FeatureConfig) -> np.ndarray:
    """Per-point D_th32: the paper's value up to ``density_full_range_m`` from the sensor, then
    falling with the square of the range to ``density_threshold_min`` (see the config)."""
    d = np.hypot(points_m[..., 0] - sensor_m[..., 0], points_m[..., 1] - sensor_m[..., 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.minimum(1.0, (config.density_full_range_m / d) ** 2)
    thr = np.maximum(config.density_threshold_min, config.density_threshold * scale)
    return np.where(np.isnan(d), config.density_threshold, thr)


def range_jumps(ranges_m: np.ndarray, ground_m: np.ndarray, threshold_m: float, step: int) -> np.ndarray:
    """Mask of ``r_diff = (r_i - r_i-1) - (r_i-1 - r_i-2) > threshold_m`` walking the columns
    with ``step`` (+1 or -1), where the rays' ground distances increase (near to far)."""
    return _jumps(ranges_m, _near_to_far(ground_m, step), threshold_m, step)


def _near_to_far(ground_m: np.ndarray, step: int) -> np.ndarray:
    """Where the ground distances of columns i-2, i-1, i (walking ``step``) increase."""
    g = ground_m if step == 1 else ground_m[:, ::-1]
    out = np.zeros(g.shape, dtype=bool)
    if g.shape[1] >= 3:
        out[:, 2:] = (g[:, 2:] > g[:, 1:-1]) & (g[:, 1:-1] > g[:, :-2])
    return out if step == 1 else out[:, ::-1]


def _jumps(ranges_m: np.ndarray, far: np.ndarray, threshold_m: float, step: int) -> np.ndarray:
    """:func:`range_jumps` given its near-to-far mask."""
    r = np.ascontiguousarray(ranges_m, dtype=np.float64)
    return _jump_mask(r, np.ascontiguousarray(far, dtype=np.bool_), float(threshold_m), int(step))


@kernel
def _jump_mask(r: np.ndarray, far: np.ndarray, threshold_m: float, step: int) -> np.ndarray:
    """At column i, walking ``step``: ``(r[i] - r[i-s]) - (r[i-s] - r[i-2s]) > threshold_m`` and
    ``far[i]``; columns without two before them in the walk are False."""
    n_l, n_c = r.shape
    out = np.zeros((n_l, n_c), dtype=np.bool_)
    first, stop = (2, n_c) if step == 1 else (0, n_c - 2)
    for laser in range(n_l):
        for col in range(first, stop):
            r1, r2 = r[laser, col - step], r[laser, col - 2 * step]
            out[laser, col] = far[laser, col] and (r[laser, col] - r1) - (r1 - r2) > threshold_m
    return out


def next_point(
    points_m: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    step: int,
    min_separation_m: float,
    max_steps: int,
) -> np.ndarray:
    """Point C: the first return after B (walking ``step``) that is more than
    ``min_separation_m`` from B, within ``max_steps`` columns; NaN rows where there is none.
    With ``min_separation_m = 0`` this is the paper's "next point" (the adjacent return)."""
    n_c = points_m.shape[1]
    if rows.size == 0:
        return np.empty((0, 3))
    offs = np.arange(1, max(max_steps, 1) + 1)
    cc = cols[:, None] + step * offs[None, :]
    inside = (cc >= 0) & (cc < n_c)
    p = points_m[rows[:, None], np.clip(cc, 0, n_c - 1)]
    dist = np.linalg.norm(p - points_m[rows, cols][:, None, :], axis=-1)
    with np.errstate(invalid="ignore"):
        ok = inside & (dist > min_separation_m)
    first = ok.argmax(axis=1)
    found = ok.any(axis=1)
    c = p[np.arange(rows.size), first]
    return np.where(found[:, None], c, np.nan)


def extract_hdl32_pairs(scan: StructuredScan, config: Hdl32FeatureConfig) -> FeaturePairs:
    """Negative-obstacle feature pairs (A, B, C) of one side HDL-32 scan (paper N §3.2).

    Empty scans (no columns or no returns) give empty pairs; a non-positive sensor height
    raises ``ScanError``.
    """
    h = sensor_height(scan, config.sensor_height_m)
    ranges = scan.ranges_m
    n_l, n_c = ranges.shape
    if n_c == 0 or n_l == 0 or np.isnan(ranges).all():
        return FeaturePairs.empty(scan.sensor)
    pts = scan.points_vehicle
    _, far_forward, far_backward = _ray_tables(scan, h)
    r_c = compensate_missing(ranges) if config.compensate_missing else ranges
    valid = ~np.isnan(ranges)
    a_all, b_all, c_all, b_cols = [], [], [], []
    for step, far in ((1, far_forward), (-1, far_backward)):
        rows, cols = np.divmod(np.flatnonzero(_jumps(r_c, far, config.jump_threshold_m, step) & valid), n_c)
        # density only where it is used: at the jump points
        dens = same_laser_density(pts, config.density_radius_m, config.density_half_window, rows, cols)
        dense = dens > density_threshold(pts[rows, cols], scan.origins_vehicle(cols), config)
        rows, cols = rows[dense], cols[dense]
        prev = cols - step
        ok_idx = (prev >= 0) & (prev < n_c)
        rows, cols, prev = rows[ok_idx], cols[ok_idx], prev[ok_idx]
        b_cols.append(cols)
        a_all.append(pts[rows, prev])
        b_all.append(pts[rows, cols])
        c_all.append(next_point(pts, rows, cols, step, config.c_min_separation_m, config.density_half_window))
    a_m, b_m, c_m = (np.concatenate(x) for x in (a_all, b_all, c_all))
    ok = pair_test(a_m, b_m, c_m, scan.origins_vehicle(np.concatenate(b_cols)), h, config.pair_test)
    return FeaturePairs(scan.sensor, a_m[ok], b_m[ok], c_m[ok])
