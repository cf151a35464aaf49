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

from negobs_gym.core.compiled import kernel
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.blocks import row_spans
from negobs_gym.detector.config import Hdl64FeatureConfig
from negobs_gym.detector.geometry import nadir_angle_from_elevation, ring_radius
from negobs_gym.detector.pair_test import pair_test
from negobs_gym.detector.pairs import FeaturePairs
from negobs_gym.detector.roi import GroundMap
from negobs_gym.errors import ScanError

RISE, FALL = 1, -1


def max_filter_ranges(ranges_m: np.ndarray, radius: int) -> np.ndarray:
    """Max filter of radius ``radius`` along each row (laser); NaN (no return) stays NaN and is
    ignored by its neighbours.

    ``fmax`` of the row against its shifts by 1..radius columns either way (``fmax`` skips NaN; a
    window is cut at the row's ends): 2 x radius passes, cheaper than a general filter for the
    small radius of §3.1, and exact (a max selects one of the values).
    """
    r = np.asarray(ranges_m, dtype=np.float64)
    out = np.empty_like(r)
    n_c = r.shape[1]
    for rows in row_spans(r.shape[0], n_c):
        src, dst = r[rows], out[rows]
        dst[:] = src
        for k in range(1, min(radius, n_c - 1) + 1):
            np.fmax(dst[:, k:], src[:, :-k], out=dst[:, k:])
            np.fmax(dst[:, :-k], src[:, k:], out=dst[:, :-k])
        dst[np.isnan(src)] = np.nan
    return out


def edge_labels(ranges_m: np.ndarray, rise_m: float, fall_m: float, half_window: int) -> np.ndarray:
    """Label rising (+1) and falling (-1) edges of each laser's range sequence.

    The signed range difference to the 5-neighbourhood (``half_window`` = 2) is
    ``r[i+j] - r[i]`` forward and ``r[i] - r[i-j]`` backward, j = 1..half_window; the one largest
    in magnitude is compared with ``rise_m`` (T+) and ``fall_m`` (T-). NaN neighbours are ignored.
    """
    r = np.asarray(ranges_m, dtype=np.float64)
    n_l, n_c = r.shape
    lags = range(1, min(half_window, n_c - 1) + 1)
    # Forward j at column i and backward j at column i + j are the same lag difference
    # r[i+j] - r[i]. A column none of whose differences exceeds min(T+, -T-) in magnitude is no
    # edge whichever wins, so the choice below runs only on the few columns near a range step.
    quiet = min(rise_m, -fall_m)
    if quiet >= 0:
        found = []
        with np.errstate(invalid="ignore"):
            for block in row_spans(n_l, n_c):
                rb = r[block]
                near_step = np.zeros(rb.shape, dtype=bool)
                for j in lags:
                    big = np.abs(rb[:, j:] - rb[:, :-j]) > quiet
                    near_step[:, : n_c - j] |= big
                    near_step[:, j:] |= big
                found.append(np.flatnonzero(near_step) + block.start * n_c)
        rows, cols = np.divmod(np.concatenate(found), n_c)  # (np.nonzero is slow on 2-D arrays)
    else:
        rows, cols = (i.ravel() for i in np.indices(r.shape))
    # candidates in the order j = 1 forward, 1 backward, 2 forward, ...; a later one replaces the
    # best so far only when strictly larger in magnitude (the first of equal magnitudes is kept);
    # a neighbour past the row's end is no candidate, as a NaN one
    best = np.zeros(rows.size)
    best_abs = np.zeros(rows.size)
    with np.errstate(invalid="ignore"):
        for j in lags:
            for lo, inside in ((cols, cols < n_c - j), (cols - j, cols >= j)):
                lo = np.clip(lo, 0, n_c - j - 1)
                v = r[rows, lo + j] - r[rows, lo]
                a = np.abs(v)
                better = inside & (a > best_abs)
                best = np.where(better, v, best)
                best_abs = np.where(better, a, best_abs)
    labels = np.zeros(r.shape, dtype=np.int8)
    labels[rows[best > rise_m], cols[best > rise_m]] = RISE
    labels[rows[best < fall_m], cols[best < fall_m]] = FALL
    return labels


def _segment_sums(
    values: np.ndarray, row: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Sum of the non-NaN ``values[row, lo:hi]`` and their count for each segment (vectorized)."""
    n_c = values.shape[1]
    lo = np.clip(lo, 0, n_c)
    hi = np.clip(hi, lo, n_c)
    lengths = hi - lo
    seg = np.repeat(np.arange(row.size), lengths)
    starts = np.cumsum(lengths) - lengths
    cols = lo[seg] + np.arange(seg.size) - starts[seg]
    v = values[row[seg], cols]
    ok = ~np.isnan(v)
    total = np.bincount(seg, weights=np.where(ok, v, 0.0), minlength=row.size)
    count = np.bincount(seg, weights=ok.astype(np.float64), minlength=row.size)
    return total, count


def _segment_mean(values: np.ndarray, row: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Mean of the non-NaN ``values[row, lo:hi]`` per segment (NaN for empty segments)."""
    total, count = _segment_sums(values, row, lo, hi)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def find_bumps(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pair each rise with the following fall: returns (row, start, end) of the bumps.

    A bump ends at a falling edge that has a rising edge after the previous falling edge; it
    starts at that last rising edge. Bounds are inclusive.
    """
    row, col = np.divmod(np.flatnonzero(labels), labels.shape[1])  # edges in row-major order
    kind = labels[row, col]
    # a fall ends a bump when the edge just before it on its row is a rise (then that rise is the
    # last one after the previous fall)
    ends = (kind[1:] == FALL) & (kind[:-1] == RISE) & (row[1:] == row[:-1])
    return row[1:][ends], col[:-1][ends], col[1:][ends]


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


@kernel
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
    searched; ``radius_m`` is per query point. Compiled: a laser's search stops at its first point
    in reach (numpy measured every point of every query's window: 7 ms of a dense frame).
    """
    n_l, n_c, _ = points_m.shape
    out = np.empty(rows.size)
    for q in range(rows.size):
        r, c = rows[q], cols[q]
        px, py, pz = points_m[r, c, 0], points_m[r, c, 1], points_m[r, c, 2]
        count = 1.0
        for rr in range(max(r - laser_window, 0), min(r + laser_window + 1, n_l)):
            if rr == r:
                continue
            for cc in range(max(c - column_window, 0), min(c + column_window + 1, n_c)):
                dx, dy, dz = points_m[rr, cc, 0] - px, points_m[rr, cc, 1] - py, points_m[rr, cc, 2] - pz
                # ((dx^2 + dy^2) + dz^2): the sum np.linalg.norm forms over a (..., 3) axis, bit for bit
                if np.sqrt(dx * dx + dy * dy + dz * dz) <= radius_m[q]:  # NaN (no return): False
                    count += 1.0
                    break
        out[q] = count
    return out


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
    where none exists. Within the window the column nearest in azimuth is used (of equally near
    ones the first)."""
    if rows.size == 0:
        return np.empty((0, 3)), np.empty((0, 3))
    azimuth = np.asarray(azimuth_rad, dtype=np.float64)
    az_b = azimuth[cols]
    tol = epsilon_rad * (1 + 1e-9) + 1e-12
    lo = np.searchsorted(azimuth, az_b - tol, side="left")
    hi = np.searchsorted(azimuth, az_b + tol, side="right")
    return _trace_pairs(
        np.ascontiguousarray(points_m, dtype=np.float64),
        np.ascontiguousarray(valid, dtype=np.bool_),
        azimuth,
        np.asarray(rows, dtype=np.int64),
        az_b,
        lo.astype(np.int64),
        hi.astype(np.int64),
    )


@kernel
def _trace_pairs(
    points_m: np.ndarray,
    valid: np.ndarray,
    azimuth_rad: np.ndarray,
    rows: np.ndarray,
    az_b: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`trace_pairs`, compiled, for B's azimuth window columns ``lo:hi``: walks down (A) and
    up (C) from B's laser to the first laser with a valid point in the window."""
    n_l = points_m.shape[0]
    a_m = np.full((rows.size, 3), np.nan)
    c_m = np.full((rows.size, 3), np.nan)
    window = np.empty(max(int((hi - lo).max()), 1), dtype=np.int64)
    cost = np.empty(window.size)
    for q in range(rows.size):
        # the window's columns nearest in azimuth first (insertion sort: stable, a few columns)
        width = hi[q] - lo[q]
        for w in range(width):
            col, c = lo[q] + w, abs(azimuth_rad[lo[q] + w] - az_b[q])
            k = w
            while k > 0 and cost[k - 1] > c:
                window[k], cost[k] = window[k - 1], cost[k - 1]
                k -= 1
            window[k], cost[k] = col, c
        for out, start, stop, step in ((a_m, rows[q] - 1, -1, -1), (c_m, rows[q] + 1, n_l, 1)):
            found = False
            for laser in range(start, stop, step):
                for w in range(width):
                    if valid[laser, window[w]]:
                        for i in range(3):
                            out[q, i] = points_m[laser, window[w], i]
                        found = True
                        break
                if found:
                    break
    return a_m, c_m


def sensor_height(scan: StructuredScan, override_m: float | None) -> float:
    """Sensor height above the ground: the config override or the mounting ``T_z``."""
    h = float(scan.translation_m[2]) if override_m is None else float(override_m)
    if not h > 0:
        raise ScanError(
            f"{scan.sensor}: sensor height {h} m must be > 0 (vehicle origin is on the ground); "
            "set sensor_height_m in the config"
        )
    return h


def _segment_points(row: np.ndarray, lo: np.ndarray, hi: np.ndarray, n_c: int):
    """(segment, row, col) of every cell of the segments ``row[k], lo[k]:hi[k]`` (clipped to the scan)."""
    lo = np.clip(lo, 0, n_c)
    lengths = np.clip(hi, lo, n_c) - lo
    seg = np.repeat(np.arange(row.size), lengths)
    cols = lo[seg] + np.arange(seg.size) - (np.cumsum(lengths) - lengths)[seg]
    return seg, row[seg], cols


def extract_hdl64_pairs(
    scan: StructuredScan, config: Hdl64FeatureConfig, ground: GroundMap | None = None
) -> FeaturePairs:
    """Negative-obstacle feature pairs (A, B, C) of one upright HDL-64 scan (paper N §3.1).

    With a ``ground`` map (the ROI step, :mod:`.roi`), a bump whose side windows (the points the
    mean-range test compares it with) hold a return on a structure cell is dropped: the gap
    between two shrubs, poles or cars on one ring is a bump of the same shape as a pit's, but its
    edges are structure, not ground. Returns an empty :class:`FeaturePairs` for scans with no
    columns or no returns. Raises ``ScanError`` if the sensor height is not positive.
    """
    h = sensor_height(scan, config.sensor_height_m)
    order = np.argsort(scan.elevation_rad, kind="stable")
    sorted_already = bool(np.all(order == np.arange(order.size)))
    ranges = scan.ranges_m if sorted_already else scan.ranges_m[order]
    n_l, n_c = ranges.shape
    valid = ~np.isnan(ranges)
    if n_c == 0 or n_l == 0 or not valid.any():
        return FeaturePairs.empty(scan.sensor)
    pts = scan.points_vehicle if sorted_already else scan.points_vehicle[order]
    r_f = max_filter_ranges(ranges, config.max_filter_radius)
    labels = edge_labels(r_f, config.edge_rise_m, config.edge_fall_m, config.edge_half_window)
    b_row, b_start, b_end = find_bumps(labels)
    if b_row.size == 0:
        return FeaturePairs.empty(scan.sensor)
    w = config.side_window
    mean_in = _segment_mean(r_f, b_row, b_start, b_end + 1)
    mean_left = _segment_mean(r_f, b_row, b_start - w, b_start)
    mean_right = _segment_mean(r_f, b_row, b_end + 1, b_end + 1 + w)
    with np.errstate(invalid="ignore"):
        keep = (mean_in > mean_left) & (mean_in > mean_right)
    b_row, b_start, b_end = b_row[keep], b_start[keep], b_end[keep]
    if ground is not None and b_row.size:
        sides = []
        for lo, hi in ((b_start - w, b_start), (b_end + 1, b_end + 1 + w)):
            seg, rows, cols = _segment_points(b_row, lo, hi, n_c)
            ok = valid[rows, cols]
            sides.append(np.bincount(seg[ok], ground.on_structure_cell(pts[rows[ok], cols[ok]]), b_row.size))
        keep = (sides[0] == 0) & (sides[1] == 0)
        b_row, b_start, b_end = b_row[keep], b_start[keep], b_end[keep]
    # density on the bump points only (the only place it is used)
    seg, rows, cols = _segment_points(b_row, b_start, b_end + 1, n_c)
    member = valid[rows, cols]
    seg, rows, cols = seg[member], rows[member], cols[member]
    t_d = ring_gap_threshold(scan.elevation_rad[order], h, config.density_factor)
    dens = point_density(
        pts, rows, cols, t_d[rows], config.density_laser_window, config.density_column_window
    )
    total = np.bincount(seg, weights=dens, minlength=b_row.size)
    count = np.bincount(seg, minlength=b_row.size)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_d = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        dense = mean_d > config.density_threshold
    cand = dense[seg]
    rows, cols = rows[cand], cols[cand]
    a_m, c_m = trace_pairs(pts, valid, scan.azimuth_rad, rows, cols, np.radians(config.epsilon_deg))
    b_m = pts[rows, cols]
    ok = pair_test(a_m, b_m, c_m, scan.origins_vehicle(cols), h, config.pair_test)
    return FeaturePairs(scan.sensor, a_m[ok], b_m[ok], c_m[ok])
