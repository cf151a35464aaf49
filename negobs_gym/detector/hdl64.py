"""Top HDL-64 negative-obstacle feature pairs (paper N §3.1).

Pipeline (each step a pure function over the ``lasers x columns`` range image):
max filter of each laser's range sequence -> rising/falling edges over the 5-neighbourhood ->
bumps (rise paired with the following fall) -> mean-range and back-wall density tests ->
ray-traced (A, B, C) search across lasers -> Eq. 14.

Laser order: rows are sorted by elevation, lowest first, so a lower index is a nearer ground hit
(A is searched on lower lasers, C on higher ones). Columns are one revolution in azimuth order;
filters do not wrap around the seam. The max-filtered ranges drive edge and bump detection only;
A, B, C are the raw returns. Density is evaluated only on bump points (the only place it is used).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter1d

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.config import Hdl64FeatureConfig
from negobs_gym.detector.geometry import nadir_angle_from_elevation, ring_radius
from negobs_gym.detector.pair_test import pair_test
from negobs_gym.detector.pairs import FeaturePairs

RISE, FALL = 1, -1


def max_filter_ranges(ranges_m: np.ndarray, radius: int) -> np.ndarray:
    """Max filter of radius ``radius`` along each row (laser); NaN (no return) stays NaN and is
    ignored by its neighbours."""
    r = np.asarray(ranges_m, dtype=np.float64)
    if r.shape[1] == 0:
        return r.copy()
    filled = np.where(np.isnan(r), -np.inf, r)
    out = maximum_filter1d(filled, size=2 * radius + 1, axis=1, mode="nearest")
    return np.where(np.isnan(r), np.nan, out)


def edge_labels(ranges_m: np.ndarray, rise_m: float, fall_m: float, half_window: int) -> np.ndarray:
    """Label rising (+1) and falling (-1) edges of each laser's range sequence.

    The signed range difference to the 5-neighbourhood (``half_window`` = 2) is
    ``r[i+j] - r[i]`` forward and ``r[i] - r[i-j]`` backward, j = 1..half_window; the one largest
    in magnitude is compared with ``rise_m`` (T+) and ``fall_m`` (T-). NaN neighbours are ignored.
    """
    r = np.asarray(ranges_m, dtype=np.float64)
    n_l, n_c = r.shape
    pad = np.full((n_l, half_window), np.nan)
    rp = np.concatenate([pad, r, pad], axis=1)
    diffs = []
    for j in range(1, half_window + 1):
        diffs.append(rp[:, half_window + j : half_window + j + n_c] - r)
        diffs.append(r - rp[:, half_window - j : half_window - j + n_c])
    d = np.stack(diffs)
    mag = np.where(np.isnan(d), -1.0, np.abs(d))
    best = np.take_along_axis(d, mag.argmax(axis=0)[None], axis=0)[0]
    labels = np.zeros(r.shape, dtype=np.int8)
    labels[best > rise_m] = RISE
    labels[best < fall_m] = FALL
    return labels


def _window_mean(cs: np.ndarray, cnt: np.ndarray, row: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Mean over columns [lo, hi) of rows ``row`` from prefix sums (NaN for empty windows)."""
    n_c = cs.shape[1] - 1
    lo = np.clip(lo, 0, n_c)
    hi = np.clip(hi, 0, n_c)
    s = cs[row, hi] - cs[row, lo]
    c = cnt[row, hi] - cnt[row, lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c > 0, s / np.maximum(c, 1), np.nan)


def find_bumps(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pair each rise with the following fall: returns (row, start, end) of the bumps.

    A bump ends at a falling edge that has a rising edge after the previous falling edge; it
    starts at that last rising edge. Bounds are inclusive.
    """
    n_l, n_c = labels.shape
    idx = np.broadcast_to(np.arange(n_c), labels.shape)
    last_rise = np.maximum.accumulate(np.where(labels == RISE, idx, -1), axis=1)
    last_fall = np.maximum.accumulate(np.where(labels == FALL, idx, -1), axis=1)
    prev_fall = np.concatenate([np.full((n_l, 1), -1), last_fall[:, :-1]], axis=1)
    ends = (labels == FALL) & (last_rise > prev_fall)
    row, end = np.nonzero(ends)
    return row, last_rise[row, end], end


def ring_gap_threshold(elevation_rad: np.ndarray, height_m: float, factor: float) -> np.ndarray:
    """Eq. 10: ``T_d64[n] = factor * max(dr_n, dr_n+1)`` from the flat-ground ring radii.

    ``dr_n`` is the ring-radius gap between laser n and n-1 (Eq. 3). Lasers whose rays miss the
    ground get NaN (no density).
    """
    ring = ring_radius(height_m, nadir_angle_from_elevation(elevation_rad))
    ring = np.where(np.isfinite(ring), ring, np.nan)
    if ring.size < 2:
        return np.full(ring.shape, np.nan)
    dr = np.diff(ring)
    dr_n = np.concatenate([dr[:1], dr])  # gap to the laser below
    dr_next = np.concatenate([dr, dr[-1:]])  # gap to the laser above
    return factor * np.maximum(dr_n, dr_next)


def point_density(
    points_m: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    radius_m: np.ndarray,
    laser_window: int,
    column_window: int,
) -> np.ndarray:
    """Number of lasers (own included) with a point within ``radius_m`` of each query point.

    Neighbour lasers ``rows +- 1..laser_window`` at columns ``cols +- column_window`` are
    searched (vectorized); ``radius_m`` is per query point.
    """
    n_l, n_c, _ = points_m.shape
    if rows.size == 0:
        return np.zeros(0)
    dm = np.concatenate([np.arange(-laser_window, 0), np.arange(1, laser_window + 1)])
    dk = np.arange(-column_window, column_window + 1)
    rr = rows[:, None, None] + dm[None, :, None]
    cc = cols[:, None, None] + dk[None, None, :]
    inside = (rr >= 0) & (rr < n_l) & (cc >= 0) & (cc < n_c)
    nb = points_m[np.clip(rr, 0, n_l - 1), np.clip(cc, 0, n_c - 1)]
    q = points_m[rows, cols][:, None, None, :]
    dist = np.linalg.norm(nb - q, axis=-1)
    with np.errstate(invalid="ignore"):
        near = inside & (dist <= radius_m[:, None, None])
    return 1.0 + near.any(axis=2).sum(axis=1)


def trace_pairs(
    points_m: np.ndarray,
    valid: np.ndarray,
    azimuth_rad: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    epsilon_rad: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Tab. 2 ray tracing: for each B = (rows, cols) the nearest lower laser with a return within
    ``+-epsilon_rad`` azimuth (A) and the nearest higher one (C). Returns (A, C) points, NaN rows
    where none exists. Within the window the column nearest in azimuth is used."""
    n_l = points_m.shape[0]
    nb = rows.size
    if nb == 0:
        return np.empty((0, 3)), np.empty((0, 3))
    az_b = azimuth_rad[cols]
    tol = epsilon_rad * (1 + 1e-9) + 1e-12
    lo = np.searchsorted(azimuth_rad, az_b - tol, side="left")
    hi = np.searchsorted(azimuth_rad, az_b + tol, side="right")
    width = int((hi - lo).max())
    win = lo[:, None] + np.arange(width)[None, :]
    in_win = win < hi[:, None]
    win = np.minimum(win, azimuth_rad.size - 1)
    v = valid[:, win] & in_win[None]  # (lasers, nb, width)
    cost = np.where(v, np.abs(azimuth_rad[win] - az_b[:, None])[None], np.inf)
    best_col = cost.argmin(axis=2)  # (lasers, nb)
    has = np.isfinite(cost.min(axis=2))  # (lasers, nb)
    laser = np.arange(n_l)[:, None]
    below = has & (laser < rows[None, :])
    above = has & (laser > rows[None, :])
    a_row = np.where(below.any(axis=0), np.where(below, laser, -1).max(axis=0), -1)
    c_row = np.where(above.any(axis=0), np.where(above, laser, n_l).min(axis=0), -1)
    out = []
    for r in (a_row, c_row):
        ok = r >= 0
        rr = np.where(ok, r, 0)
        cc = win[np.arange(nb), best_col[rr, np.arange(nb)]]
        p = points_m[rr, cc]
        out.append(np.where(ok[:, None], p, np.nan))
    return out[0], out[1]


def sensor_height(scan: StructuredScan, override_m: float | None) -> float:
    """Sensor height above the ground: the config override or the mounting ``T_z``."""
    h = float(scan.translation_m[2]) if override_m is None else float(override_m)
    if not h > 0:
        raise ValueError(
            f"{scan.sensor}: sensor height {h} m must be > 0 (vehicle origin is on the ground); "
            "set sensor_height_m in the config"
        )
    return h


def extract_hdl64_pairs(scan: StructuredScan, config: Hdl64FeatureConfig) -> FeaturePairs:
    """Negative-obstacle feature pairs (A, B, C) of one upright HDL-64 scan (paper N §3.1).

    Returns an empty :class:`FeaturePairs` for scans with no columns or no returns. Raises
    ``ValueError`` if the sensor height is not positive.
    """
    h = sensor_height(scan, config.sensor_height_m)
    order = np.argsort(scan.elevation_rad, kind="stable")
    ranges = scan.ranges_m[order]
    n_l, n_c = ranges.shape
    if n_c == 0 or n_l == 0 or np.isnan(ranges).all():
        return FeaturePairs.empty(scan.sensor)
    pts = scan.points_vehicle[order]
    valid = ~np.isnan(ranges)
    r_f = max_filter_ranges(ranges, config.max_filter_radius)
    labels = edge_labels(r_f, config.edge_rise_m, config.edge_fall_m, config.edge_half_window)
    b_row, b_start, b_end = find_bumps(labels)
    if b_row.size == 0:
        return FeaturePairs.empty(scan.sensor)
    zero = np.zeros((n_l, 1))
    cs = np.concatenate([zero, np.cumsum(np.nan_to_num(r_f), axis=1)], axis=1)
    cnt = np.concatenate([zero, np.cumsum(valid, axis=1)], axis=1)
    w = config.side_window
    mean_in = _window_mean(cs, cnt, b_row, b_start, b_end + 1)
    mean_left = _window_mean(cs, cnt, b_row, b_start - w, b_start)
    mean_right = _window_mean(cs, cnt, b_row, b_end + 1, b_end + 1 + w)
    with np.errstate(invalid="ignore"):
        keep = (mean_in > mean_left) & (mean_in > mean_right)
    b_row, b_start, b_end = b_row[keep], b_start[keep], b_end[keep]
    # bump membership mask, then density on bump points only
    mark = np.zeros((n_l, n_c + 1), dtype=np.int32)
    np.add.at(mark, (b_row, b_start), 1)
    np.add.at(mark, (b_row, b_end + 1), -1)
    member = (np.cumsum(mark, axis=1)[:, :n_c] > 0) & valid
    rows, cols = np.nonzero(member)
    t_d = ring_gap_threshold(scan.elevation_rad[order], h, config.density_factor)
    dens = np.zeros((n_l, n_c))
    dens[rows, cols] = point_density(
        pts, rows, cols, t_d[rows], config.density_laser_window, config.density_column_window
    )
    ds = np.concatenate([zero, np.cumsum(dens, axis=1)], axis=1)
    mean_d = _window_mean(ds, cnt, b_row, b_start, b_end + 1)
    with np.errstate(invalid="ignore"):
        dense = mean_d > config.density_threshold
    bump_id = np.full((n_l, n_c + 1), 0, dtype=np.int32)
    np.add.at(bump_id, (b_row[dense], b_start[dense]), 1)
    np.add.at(bump_id, (b_row[dense], b_end[dense] + 1), -1)
    cand = (np.cumsum(bump_id, axis=1)[:, :n_c] > 0) & valid
    rows, cols = np.nonzero(cand)
    a_m, c_m = trace_pairs(pts, valid, scan.azimuth_rad, rows, cols, np.radians(config.epsilon_deg))
    b_m = pts[rows, cols]
    ok = pair_test(a_m, b_m, c_m, scan.translation_m, h, config.pair_test)
    return FeaturePairs(scan.sensor, a_m[ok], b_m[ok], c_m[ok])
