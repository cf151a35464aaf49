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


def overlap_distance(a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """Row-wise pair distance [m] between (n, 2) segments a1-b1 and a2-b2 (see the module docstring)."""
    u1 = _unit(b1 - a1)
    u2 = _unit(b2 - a2)
    sign = np.where(np.einsum("nk,nk->n", u1, u2) < 0.0, -1.0, 1.0)
    axis = _unit(u1 + sign[:, None] * u2)
    ta1, tb1 = np.einsum("nk,nk->n", a1, axis), np.einsum("nk,nk->n", b1, axis)
    ta2, tb2 = np.einsum("nk,nk->n", a2, axis), np.einsum("nk,nk->n", b2, axis)
    lo = np.maximum(np.minimum(ta1, tb1), np.minimum(ta2, tb2))
    hi = np.minimum(np.maximum(ta1, tb1), np.maximum(ta2, tb2))
    mean_gap = 0.5 * (
        np.linalg.norm(_at(a1, b1, ta1, tb1, lo) - _at(a2, b2, ta2, tb2, lo), axis=1)
        + np.linalg.norm(_at(a1, b1, ta1, tb1, hi) - _at(a2, b2, ta2, tb2, hi), axis=1)
    )
    ends1 = np.stack([a1, b1], axis=1)[:, :, None, :]
    ends2 = np.stack([a2, b2], axis=1)[:, None, :, :]
    nearest_ends = np.linalg.norm(ends1 - ends2, axis=-1).reshape(len(a1), 4).min(axis=1)
    return np.where(hi >= lo, mean_gap, nearest_ends)


def close_pairs(
    a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray, max_distance_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All (i, j, distance) with :func:`overlap_distance` of pair i of set 1 and pair j of set 2 <= max.

    Inputs are (n, 2) ground-plane points. Two pairs that close have a point of one segment within
    ``max_distance_m`` of a point of the other (where their projections overlap, one of the two
    end distances averaged is at most the mean; elsewhere the nearest ends are). Each segment is
    sampled every ``max_distance_m`` (so every point of it lies within half that of a sample), a
    KD-tree finds the samples within twice the distance, and only the pairs they name are
    measured: the cost grows with the samples and their close neighbours, never with all pairs.
    """
    if len(a1) == 0 or len(a2) == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty, np.empty(0)
    step = max_distance_m
    owner1, pts1 = _samples(a1, b1, step)
    owner2, pts2 = _samples(a2, b2, step)
    cand = cKDTree(pts1).sparse_distance_matrix(cKDTree(pts2), max_distance_m + step, output_type="ndarray")
    key = np.unique(owner1[cand["i"]] * len(a2) + owner2[cand["j"]])
    i, j = key // len(a2), key % len(a2)
    d = overlap_distance(a1[i], b1[i], a2[j], b2[j])
    close = d <= max_distance_m
    return i[close], j[close], d[close]


def _samples(a: np.ndarray, b: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along each segment a-b at most ``step`` apart, both ends included, and their owner."""
    n = np.ceil(np.linalg.norm(b - a, axis=1) / step).astype(np.int64) + 1
    owner = np.repeat(np.arange(len(a)), n)
    first = np.cumsum(n) - n
    t = (np.arange(owner.size) - first[owner]) / np.maximum(n[owner] - 1, 1)
    return owner, a[owner] + t[:, None] * (b[owner] - a[owner])


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, n, out=np.tile([1.0, 0.0], (len(v), 1)), where=n > 0)


def _at(a: np.ndarray, b: np.ndarray, ta: np.ndarray, tb: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Point of segment a-b whose projection on the axis is ``t`` (its midpoint if it is perpendicular)."""
    span = tb - ta
    s = np.divide(t - ta, span, out=np.full_like(t, 0.5), where=np.abs(span) > 1e-12)
    return a + np.clip(s, 0.0, 1.0)[:, None] * (b - a)
