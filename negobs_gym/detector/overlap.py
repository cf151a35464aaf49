"""Compiled kernels of paper N's pair distance (§3.3; defined in :mod:`negobs_gym.detector.pairs`).

Fusion matching and DBSCAN measure every candidate that a KD-tree on the pairs' midpoints finds:
~175,000 and ~120,000 per dense frame. Done with numpy, each candidate's distance and its
line-side bound (below) took some 40 array operations on gathered columns: 26 ms of the dense
frame's 92 ms. Here one compiled loop does both per candidate, reading the two pairs' rows of a
segment table: 2.7 ms for the fusion's 175,000 (docs/detector_features.md, "Runtime").

The arithmetic is the numpy definition's, operation by operation (numba compiles without
fast-math, so nothing is reordered or fused): the distances are bit for bit those of the
reference in ``tests/detector/test_reference.py``.

Segment table: one row per pair, the columns below (:data:`COLUMNS`).
"""

from __future__ import annotations

import numpy as np

from negobs_gym.core.compiled import kernel

COLUMNS = ("ax", "ay", "bx", "by", "ex", "ey", "ux", "uy", "offset")
"""A, B, e = B - A, the unit A->B direction u ((1, 0) for a zero-length pair) and the signed
distance of the pair's line from the origin along (-uy, ux)."""

_PERPENDICULAR = 1e-12  # |projected length| below which a pair is taken as perpendicular to the axis


@kernel
def _unit(x: float, y: float) -> tuple[float, float]:
    n = np.sqrt(x * x + y * y)
    if n > 0.0:
        return x / n, y / n
    return 1.0, 0.0


@kernel
def _norm(x: float, y: float) -> float:
    return np.sqrt(x * x + y * y)


@kernel
def _point_at(s: np.ndarray, k: int, ta: float, tb: float, t: float) -> tuple[float, float]:
    """Point of pair k whose projection on the axis is t (its midpoint if it is perpendicular)."""
    span = tb - ta
    f = (t - ta) / span if abs(span) > _PERPENDICULAR else 0.5
    f = min(max(f, 0.0), 1.0)
    return s[k, 0] + f * s[k, 4], s[k, 1] + f * s[k, 5]


@kernel
def _distance(s1: np.ndarray, k: int, s2: np.ndarray, m: int) -> float:
    """Overlap distance of pair k of ``s1`` and pair m of ``s2``."""
    a1x, a1y, b1x, b1y = s1[k, 0], s1[k, 1], s1[k, 2], s1[k, 3]
    a2x, a2y, b2x, b2y = s2[m, 0], s2[m, 1], s2[m, 2], s2[m, 3]
    u1x, u1y, u2x, u2y = s1[k, 6], s1[k, 7], s2[m, 6], s2[m, 7]
    sign = -1.0 if u1x * u2x + u1y * u2y < 0.0 else 1.0
    ax, ay = _unit(u1x + sign * u2x, u1y + sign * u2y)  # the bisector
    ta1, tb1 = a1x * ax + a1y * ay, b1x * ax + b1y * ay
    ta2, tb2 = a2x * ax + a2y * ay, b2x * ax + b2y * ay
    lo = max(min(ta1, tb1), min(ta2, tb2))
    hi = min(max(ta1, tb1), max(ta2, tb2))
    if hi >= lo:  # mean gap at the two ends of the overlap
        p1x, p1y = _point_at(s1, k, ta1, tb1, lo)
        p2x, p2y = _point_at(s2, m, ta2, tb2, lo)
        gap_lo = _norm(p1x - p2x, p1y - p2y)
        p1x, p1y = _point_at(s1, k, ta1, tb1, hi)
        p2x, p2y = _point_at(s2, m, ta2, tb2, hi)
        return 0.5 * (gap_lo + _norm(p1x - p2x, p1y - p2y))
    return min(  # no overlap: nearest end points
        min(_norm(a1x - a2x, a1y - a2y), _norm(a1x - b2x, a1y - b2y)),
        min(_norm(b1x - a2x, b1y - a2y), _norm(b1x - b2x, b1y - b2y)),
    )


@kernel
def _within_reach_of_line(line: np.ndarray, k: int, other: np.ndarray, m: int, reach: float) -> bool:
    """False where pair m lies wholly on one side of pair k's line, farther than ``reach``."""
    ux, uy, offset = line[k, 6], line[k, 7], line[k, 8]
    side_a = ux * other[m, 1] - uy * other[m, 0] - offset
    side_b = ux * other[m, 3] - uy * other[m, 2] - offset
    return min(side_a, side_b) <= reach and max(side_a, side_b) >= -reach


@kernel
def measure_candidates(
    s1: np.ndarray,
    s2: np.ndarray,
    i: np.ndarray,
    j: np.ndarray,
    reach1: np.ndarray,
    reach2: np.ndarray,
    max_distance_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(close, distance) per candidate (i[q], j[q]) of segment tables ``s1``, ``s2``.

    A candidate is measured only if each pair reaches the other's line within
    min(reach1[i], reach2[j]) (a lower bound of the distance: every point pair the overlap distance
    measures joins the two segments, so crosses the gap between one line and the other segment);
    close = measured and distance <= ``max_distance_m``. Unmeasured distances are NaN.
    """
    n = i.shape[0]
    close = np.zeros(n, dtype=np.bool_)
    distance = np.full(n, np.nan)
    for q in range(n):
        k, m = i[q], j[q]
        reach = min(reach1[k], reach2[m])
        if _within_reach_of_line(s1, k, s2, m, reach) and _within_reach_of_line(s2, m, s1, k, reach):
            d = _distance(s1, k, s2, m)
            distance[q] = d
            close[q] = d <= max_distance_m
    return close, distance


@kernel
def row_distances(s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """Overlap distance of row k of ``s1`` and row k of ``s2``, for every k."""
    out = np.empty(s1.shape[0])
    for k in range(s1.shape[0]):
        out[k] = _distance(s1, k, s2, k)
    return out
