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

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from negobs_gym.core import libm
from negobs_gym.detector.overlap import measure_candidates, row_distances
from negobs_gym.errors import GeometryError, ScanError


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


def _segment_table(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, 9) rows of (n, 2) ground-plane pairs A-B, the columns of
    :data:`negobs_gym.detector.overlap.COLUMNS`, computed once per set."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 2)
    ax, ay, bx, by = a[:, 0], a[:, 1], b[:, 0], b[:, 1]
    ex, ey = bx - ax, by - ay
    ux, uy = _unit_xy(ex, ey)
    return np.stack([ax, ay, bx, by, ex, ey, ux, uy, ux * ay - uy * ax], axis=1)


def overlap_distance(a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """Row-wise pair distance [m] between (n, 2) segments a1-b1 and a2-b2 (see the module docstring)."""
    s1, s2 = _segment_table(a1, b1), _segment_table(a2, b2)
    if len(s1) != len(s2):
        raise GeometryError(f"overlap_distance: segments a1-b1 have {len(s1)} rows, a2-b2 {len(s2)}")
    return row_distances(s1, s2)


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
    other's line are dropped unmeasured (a lower bound of the distance); the rest are measured
    (:func:`negobs_gym.detector.overlap.measure_candidates`). The order of the returned triples is
    unspecified.
    """
    if len(a1) == 0 or len(a2) == 0:
        return _joined([])
    limit = np.broadcast_to(np.asarray(max_distance_m, dtype=np.float64), (len(a2),))
    classes2 = [
        (idx, half, float(limit[idx].max()), cKDTree(0.5 * (a2[idx] + b2[idx])))
        for idx, half in _length_classes(a2, b2)
    ]
    found = []
    for idx1, half1 in _length_classes(a1, b1):
        tree1 = cKDTree(0.5 * (a1[idx1] + b1[idx1]))
        for idx2, half2, limit2, tree2 in classes2:
            cand = tree1.sparse_distance_matrix(tree2, limit2 + half1 + half2, output_type="ndarray")
            found.append((idx1[cand["i"]], idx2[cand["j"]]))
    reach1 = np.full(len(a1), np.inf)
    i, j, d = _measured(_segment_table(a1, b1), _segment_table(a2, b2), found, reach1, limit, limit.max())
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
    classes = [(idx, half, cKDTree(0.5 * (a[idx] + b[idx]))) for idx, half in _length_classes(a, b)]
    found = []
    for k, (idx1, half1, tree1) in enumerate(classes):
        within = tree1.query_pairs(max_distance_m + half1 + half1, output_type="ndarray")  # i < j
        found.append((idx1[within[:, 0]], idx1[within[:, 1]]))
        for idx2, half2, tree2 in classes[k + 1 :]:
            cand = tree1.sparse_distance_matrix(tree2, max_distance_m + half1 + half2, output_type="ndarray")
            found.append((idx1[cand["i"]], idx2[cand["j"]]))
    s = _segment_table(a, b)
    reach = np.full(len(a), float(max_distance_m))
    if limit_m is not None:
        reach = np.minimum(np.asarray(limit_m, dtype=np.float64), reach)
    i, j, d = _measured(s, s, found, reach, reach, max_distance_m)
    every = np.arange(len(s))
    found_self = _measured(s, s, [(every, every)], reach, reach, max_distance_m)
    return (
        np.concatenate([i, j, found_self[0]]),
        np.concatenate([j, i, found_self[1]]),
        np.concatenate([d, d, found_self[2]]),
    )


def _measured(
    s1: np.ndarray,
    s2: np.ndarray,
    candidates: list[tuple[np.ndarray, np.ndarray]],
    reach1: np.ndarray,
    reach2: np.ndarray,
    max_distance_m: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i, j, distance) of the candidate (i, j) of segment tables ``s1``, ``s2`` within
    ``max_distance_m``; a candidate farther than min(reach1[i], reach2[j]) from one pair's line may
    be left out unmeasured."""
    if not candidates:
        return _joined([])
    i = np.concatenate([c[0] for c in candidates]).astype(np.int64, copy=False)
    j = np.concatenate([c[1] for c in candidates]).astype(np.int64, copy=False)
    close, d = measure_candidates(
        s1, s2, i, j, reach1 + _BOUND_MARGIN_M, reach2 + _BOUND_MARGIN_M, float(max_distance_m)
    )
    return i[close], j[close], d[close]


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
# a set of at most this many pairs is one length class: for the few hundred pairs of an env frame a
# KD-tree per class and a query per two classes cost more than the extra candidates they spare
# (fusion + DBSCAN 2.5 ms less per OffroadNav frame, docs/detector_features.md); dense frames keep
# their classes. Any split gives the same result: a class's radius covers its longest pair.
_ONE_CLASS_MAX_PAIRS = 1000


def _length_classes(a: np.ndarray, b: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """(indices, longest half-length) of the pairs in each non-empty length class."""
    length = _norm(*(b - a).T)
    if 0 < len(length) <= _ONE_CLASS_MAX_PAIRS:
        return [(np.arange(len(length)), 0.5 * float(length.max()))]
    octaves = libm.log2(np.maximum(length, _SHORTEST_CLASS_M) / _SHORTEST_CLASS_M)
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
