"""Negative-obstacle feature point pairs (paper N §3): the record passed from the per-sensor
feature extractors to the multi-frame fusion.

A pair (A, B) spans the gap that a negative obstacle leaves in a scan line: ``A`` is the last ground
point on the near side, ``B`` the first point on the far side (the back wall / far rim). ``C`` is the
point after ``B`` on the same ray direction (used by the Eq. 14 back-wall test).

Distance between two pairs (paper N §3.3, stated for DBSCAN and used here for fusion matching too):
the mean distance over the part where they overlap along the laser direction. In the ground plane:

- the common direction is the bisector of the two pairs' A->B directions (sign-aligned), so the
  distance is symmetric;
- both segments are projected on it; where the projections overlap, the distance is the mean of the
  point-to-point distances at the two ends of the overlap (exact while the segments do not cross);
- where they do not overlap, it is the distance between their nearest end points, so pairs one
  behind the other along the same laser line still count as close when their ends are.

Unlike a midpoint distance, this one does not move when a ring sweeps across the rim and the
pair's A jumps to the next laser: overlapping pairs in one azimuth stay at their lateral offset.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from negobs_gym.detector.blocks import BLOCK_ELEMENTS, spans
from negobs_gym.errors import ScanError


@dataclass(frozen=True, eq=False)
class FeaturePairs:
    """A batch of feature point pairs of one sensor in one frame, in the vehicle frame.

    Attributes:
        sensor: Name of the sensor that produced them (e.g. ``"hdl64"``).
        a_m: (n, 3) near-side points A [m].
        b_m: (n, 3) far-side points B [m].
        c_m: (n, 3) points C beyond B [m] (NaN rows allowed where C is unknown).
    """

    sensor: str
    a_m: np.ndarray
    b_m: np.ndarray
    c_m: np.ndarray

    def __post_init__(self) -> None:
        for name in ("a_m", "b_m", "c_m"):
            arr = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1, 3)
            object.__setattr__(self, name, arr)
        n = self.a_m.shape[0]
        if self.b_m.shape[0] != n or self.c_m.shape[0] != n:
            raise ScanError(
                f"{self.sensor}: A, B, C must have the same number of rows, got "
                f"{self.a_m.shape[0]}, {self.b_m.shape[0]}, {self.c_m.shape[0]}"
            )

    def __len__(self) -> int:
        return int(self.a_m.shape[0])

    @classmethod
    def empty(cls, sensor: str) -> FeaturePairs:
        """No pairs."""
        z = np.empty((0, 3))
        return cls(sensor, z, z, z)


def range_scale(a_xy: np.ndarray, b_xy: np.ndarray, full_range_m: float, max_scale: float) -> np.ndarray:
    """Per pair: 1 up to ``full_range_m`` (distance of its midpoint from the vehicle origin), then
    range / ``full_range_m``, at most ``max_scale``: how far a distance threshold set for near pairs
    stretches for a pair at range, where the scan lines that form pairs lie farther apart."""
    mid = 0.5 * (np.asarray(a_xy, dtype=np.float64)[:, :2] + np.asarray(b_xy, dtype=np.float64)[:, :2])
    rng = np.sqrt(mid[:, 0] ** 2 + mid[:, 1] ** 2)
    return np.clip(rng / full_range_m, 1.0, max_scale)


_Found = tuple[np.ndarray, np.ndarray, np.ndarray]  # (i, j, distance) of close pairs


class _Segments(NamedTuple):
    """Per-pair columns of a set of (n, 2) ground-plane pairs, computed once per set."""

    ax: np.ndarray
    ay: np.ndarray
    bx: np.ndarray
    by: np.ndarray
    ex: np.ndarray  # b - a
    ey: np.ndarray
    ux: np.ndarray  # unit A->B direction (1, 0) for a zero-length pair
    uy: np.ndarray
    offset: np.ndarray  # signed distance of the pair's line from the origin along (-uy, ux)


def _segments(a: np.ndarray, b: np.ndarray) -> _Segments:
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 2)
    ax, ay, bx, by = (np.ascontiguousarray(v) for v in (a[:, 0], a[:, 1], b[:, 0], b[:, 1]))
    ex, ey = bx - ax, by - ay
    ux, uy = _unit_xy(ex, ey)
    return _Segments(ax, ay, bx, by, ex, ey, ux, uy, ux * ay - uy * ax)


def overlap_distance(a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """Row-wise pair distance [m] between (n, 2) segments a1-b1 and a2-b2 (see the module docstring)."""
    s1, s2 = _segments(a1, b1), _segments(a2, b2)
    n = len(s1.ax)
    if len(s2.ax) != n:
        raise ValueError(f"overlap_distance: {n} and {len(s2.ax)} rows")
    out = np.empty(n)
    for block in spans(n):
        rows = np.arange(block.start, block.stop)
        out[block] = _pair_distance(s1, rows, s2, rows)
    return out


def _pair_distance(s1: _Segments, i: np.ndarray, s2: _Segments, j: np.ndarray) -> np.ndarray:
    """:func:`overlap_distance` of pair ``i`` of ``s1`` and pair ``j`` of ``s2`` (one block)."""
    a1x, a1y, b1x, b1y, e1x, e1y, u1x, u1y = (v[i] for v in s1[:8])
    a2x, a2y, b2x, b2y, e2x, e2y, u2x, u2y = (v[j] for v in s2[:8])
    sign = np.where(u1x * u2x + u1y * u2y < 0.0, -1.0, 1.0)
    ax, ay = _unit_xy(u1x + sign * u2x, u1y + sign * u2y)
    ta1, tb1 = a1x * ax + a1y * ay, b1x * ax + b1y * ay
    ta2, tb2 = a2x * ax + a2y * ay, b2x * ax + b2y * ay
    lo = np.maximum(np.minimum(ta1, tb1), np.minimum(ta2, tb2))
    hi = np.minimum(np.maximum(ta1, tb1), np.maximum(ta2, tb2))
    gaps = []  # mean gap at the two ends of the overlap (used where there is one: most candidates)
    for t in (lo, hi):
        p1x, p1y = _at(a1x, a1y, e1x, e1y, ta1, tb1, t)
        p2x, p2y = _at(a2x, a2y, e2x, e2y, ta2, tb2, t)
        gaps.append(_norm(p1x - p2x, p1y - p2y))
    out = 0.5 * (gaps[0] + gaps[1])
    k = np.flatnonzero(~(hi >= lo))  # no overlap: nearest end points
    if k.size:
        a1x, a1y, b1x, b1y = a1x[k], a1y[k], b1x[k], b1y[k]
        a2x, a2y, b2x, b2y = a2x[k], a2y[k], b2x[k], b2y[k]
        out[k] = np.minimum(
            np.minimum(_norm(a1x - a2x, a1y - a2y), _norm(a1x - b2x, a1y - b2y)),
            np.minimum(_norm(b1x - a2x, b1y - a2y), _norm(b1x - b2x, b1y - b2y)),
        )
    return out


def _may_be_close(
    s1: _Segments, i: np.ndarray, s2: _Segments, j: np.ndarray, reach_m: float | np.ndarray
) -> np.ndarray:
    """Ascending indices into (i, j) of the candidates that may lie within ``reach_m`` (one value,
    or one per candidate).

    A candidate is dropped where pair j of ``s2`` lies wholly on one side of pair i's line farther
    than ``reach_m`` (or pair i of pair j's line): a lower bound of their distance, since every
    point pair the overlap distance measures joins the two segments and so crosses the gap between
    one line and the other segment.
    """
    keep = np.arange(len(i))
    for s_line, s_other, on_line, other in ((s1, s2, i, j), (s2, s1, j, i)):
        ia, ib = on_line[keep], other[keep]
        reach = reach_m if np.ndim(reach_m) == 0 else reach_m[keep]
        ux, uy, off = s_line.ux[ia], s_line.uy[ia], s_line.offset[ia]
        side_a = ux * s_other.ay[ib] - uy * s_other.ax[ib] - off
        side_b = ux * s_other.by[ib] - uy * s_other.bx[ib] - off
        keep = keep[(np.minimum(side_a, side_b) <= reach) & (np.maximum(side_a, side_b) >= -reach)]
    return keep


# Margin of the line-side bound: far above the rounding of metre-scale coordinates (~1e-14 m), so a
# pair whose computed distance passes the test is never dropped by the bound.
_BOUND_MARGIN_M = 1e-6


def close_pairs(
    a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray, max_distance_m: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All (i, j, distance) with :func:`overlap_distance` of pair i of set 1 and pair j of set 2 <= max.

    Inputs are (n, 2) ground-plane points; ``max_distance_m`` is one value or one per pair of set 2.
    Two pairs that close have points within the maximum of each other, so their midpoints lie within
    it plus half of each pair's length. Pairs are grouped by length (classes growing by 2^(1/3) from
    :data:`_SHORTEST_CLASS_M`); for each two classes a KD-tree on the midpoints finds the candidates
    within the class's largest maximum plus the two classes' longest half-lengths. A candidate's
    midpoints are thus never farther apart than 1.26 times what its own lengths allow, so the work
    grows with the pairs and their near neighbours (n log n), not with all pairs, however long the
    longest pair is. Candidates one of which lies wholly beyond their maximum on one side of the
    other's line are dropped unmeasured (a lower bound of the distance, :func:`_may_be_close`); the
    rest are measured. The order of the returned triples is unspecified.
    """
    if len(a1) == 0 or len(a2) == 0:
        return _joined([])
    s1, s2 = _segments(a1, b1), _segments(a2, b2)
    limit = np.broadcast_to(np.asarray(max_distance_m, dtype=np.float64), (len(a2),))
    classes2 = [
        (idx, half, float(limit[idx].max()), cKDTree(0.5 * (a2[idx] + b2[idx])))
        for idx, half in _length_classes(a2, b2)
    ]

    def candidates() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        for idx1, half1 in _length_classes(a1, b1):
            tree1 = cKDTree(0.5 * (a1[idx1] + b1[idx1]))
            for idx2, half2, limit2, tree2 in classes2:
                reach = limit2 + half1 + half2
                cand = tree1.sparse_distance_matrix(tree2, reach, output_type="ndarray")
                yield idx1[cand["i"]], idx2[cand["j"]]

    i, j, d = _measured(s1, s2, candidates(), float(limit.max()), lambda ib, jb: limit[jb])
    close = d <= limit[j]
    return i[close], j[close], d[close]


def close_pairs_within(
    a: np.ndarray, b: np.ndarray, max_distance_m: float, limit_m: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``close_pairs(a, b, a, b, max_distance_m)`` (every pair with itself included), measuring each
    two pairs once: :func:`overlap_distance` is symmetric bit for bit (swapping the pairs swaps or
    negates every intermediate exactly), so (j, i) gets the distance of (i, j).

    ``limit_m`` (optional, one per pair): two pairs farther apart than the smaller of their limits
    may be left out unmeasured; every two within both limits and ``max_distance_m`` are returned
    (for a caller whose own test is tighter per pair; it applies that test to the result).
    """
    if len(a) == 0:
        return _joined([])
    s = _segments(a, b)
    classes = [(idx, half, cKDTree(0.5 * (a[idx] + b[idx]))) for idx, half in _length_classes(a, b)]
    limit = None if limit_m is None else np.minimum(np.asarray(limit_m, dtype=np.float64), max_distance_m)

    def candidates() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        for k, (idx1, half1, tree1) in enumerate(classes):
            within = tree1.query_pairs(max_distance_m + half1 + half1, output_type="ndarray")  # i < j
            yield idx1[within[:, 0]], idx1[within[:, 1]]
            for idx2, half2, tree2 in classes[k + 1 :]:
                reach = max_distance_m + half1 + half2
                cand = tree1.sparse_distance_matrix(tree2, reach, output_type="ndarray")
                yield idx1[cand["i"]], idx2[cand["j"]]

    bound = None if limit is None else (lambda ib, jb: np.minimum(limit[ib], limit[jb]))
    i, j, d = _measured(s, s, candidates(), max_distance_m, bound)
    every = np.arange(len(s.ax))
    found_self = _measured(s, s, iter([(every, every)]), max_distance_m)
    return (
        np.concatenate([i, j, found_self[0]]),
        np.concatenate([j, i, found_self[1]]),
        np.concatenate([d, d, found_self[2]]),
    )


def _measured(
    s1: _Segments,
    s2: _Segments,
    candidates: Iterator[tuple[np.ndarray, np.ndarray]],
    max_distance_m: float,
    bound: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> _Found:
    """(i, j, distance) of the candidate (i, j) within ``max_distance_m``. ``bound(i, j)``
    (optional, <= ``max_distance_m``): per candidate, a distance beyond which it may be left out
    unmeasured.

    Candidates are bounded in blocks of about :data:`BLOCK_ELEMENTS` (the many small batches of the
    length classes gathered first) and the survivors measured in blocks of about as many: the bound
    leaves a sixth of the fusion's candidates, and measuring each bounded block alone spent most of
    its time in the overhead of ~40 numpy calls on a few thousand elements.
    """
    found = []
    kept: list[tuple[np.ndarray, np.ndarray]] = []
    n_kept = 0
    for i, j in _gathered(itertools.chain(candidates, [None])):
        if i is not None:
            for block in spans(len(i)):
                ib, jb = i[block], j[block]
                reach = (max_distance_m if bound is None else bound(ib, jb)) + _BOUND_MARGIN_M
                keep = _may_be_close(s1, ib, s2, jb, reach)
                kept.append((ib[keep], jb[keep]))
                n_kept += len(keep)
        if n_kept >= BLOCK_ELEMENTS or (i is None and n_kept):
            ik = np.concatenate([k[0] for k in kept])
            jk = np.concatenate([k[1] for k in kept])
            kept, n_kept = [], 0
            for block in spans(len(ik)):
                ib, jb = ik[block], jk[block]
                d = _pair_distance(s1, ib, s2, jb)
                close = d <= max_distance_m
                found.append((ib[close], jb[close], d[close]))
    return _joined(found)


def _gathered(
    parts: Iterator[tuple[np.ndarray, np.ndarray] | None],
) -> Iterator[tuple[np.ndarray, np.ndarray] | tuple[None, None]]:
    """The (i, j) parts joined into batches of at least :data:`BLOCK_ELEMENTS` (the last may be
    smaller); ``None`` in ``parts`` flushes and is passed on as ``(None, None)``."""
    batch: list[tuple[np.ndarray, np.ndarray]] = []
    n_batch = 0
    for part in parts:
        if part is not None:
            batch.append(part)
            n_batch += len(part[0])
            if n_batch < BLOCK_ELEMENTS:
                continue
        if batch:
            yield np.concatenate([p[0] for p in batch]), np.concatenate([p[1] for p in batch])
            batch, n_batch = [], 0
        if part is None:
            yield None, None


def _joined(
    found: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (i, j, distance) parts concatenated (int64 indices)."""
    if not found:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty, np.empty(0)
    i, j, d = zip(*found, strict=True)
    return np.concatenate(i).astype(np.int64), np.concatenate(j).astype(np.int64), np.concatenate(d)


_SHORTEST_CLASS_M = 0.25  # pairs up to this long form the first length class (Eq. 14: w_min 0.30 m)
# length classes per doubling: finer classes give tighter candidate radii (3: ~30 % fewer candidates
# than 1 on the dense pit field, and a quarter of the KD-tree time), more trees beyond that gain nothing
_CLASSES_PER_OCTAVE = 3


def _length_classes(a: np.ndarray, b: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """(indices, longest half-length) of the pairs in each non-empty length class."""
    length = _norm(*(b - a).T)
    octaves = np.log2(np.maximum(length, _SHORTEST_CLASS_M) / _SHORTEST_CLASS_M)
    cls = np.ceil(_CLASSES_PER_OCTAVE * octaves).astype(np.int64)
    order = np.argsort(cls, kind="stable")
    bounds = np.flatnonzero(np.diff(cls[order])) + 1
    return [(idx, 0.5 * float(length[idx].max())) for idx in np.split(order, bounds)]


def _norm(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Length of (x, y) (np.hypot is several times slower and its overflow guard is not needed here)."""
    return np.sqrt(x * x + y * y)


def _unit_xy(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of (x, y); zero vectors become (1, 0)."""
    n = _norm(x, y)
    ok = n > 0
    safe = np.where(ok, n, 1.0)
    return np.where(ok, x / safe, 1.0), np.where(ok, y / safe, 0.0)


def _at(
    ax: np.ndarray,
    ay: np.ndarray,
    ex: np.ndarray,
    ey: np.ndarray,
    ta: np.ndarray,
    tb: np.ndarray,
    t: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Point of segment a -> a + e whose projection on the axis is ``t`` (its midpoint if it is
    perpendicular)."""
    span = tb - ta
    s = np.divide(t - ta, span, out=np.full_like(t, 0.5), where=np.abs(span) > 1e-12)
    s = np.clip(s, 0.0, 1.0)
    return ax + s * ex, ay + s * ey
