"""DBSCAN of fused feature pairs with paper N's pair distance, one convex outline per cluster (§3.3 step 3).

The distance is :func:`negobs_gym.detector.pairs.overlap_distance`. Only pairs that close are
measured (:func:`~negobs_gym.detector.pairs.close_pairs_within`): memory and time grow with the
neighbours, not with the square of the pairs.

DBSCAN on that neighbour list is its definition in three vectorized steps (:func:`dbscan_labels`):
core pairs by weighted neighbour count, clusters as the connected components of the core pairs (union-find),
border pairs into the first cluster that reaches them. It numbers clusters as scikit-learn's DBSCAN
does and gives its labels exactly (``ClusteringConfig.dbscan_backend = "sklearn"`` runs scikit-learn
on the same graph; ``tests/detector/test_clustering.py`` compares them). scikit-learn sums each
pair's neighbour weights in a Python loop and wants the graph sorted by row and distance: on a dense
frame (~1,900 pairs, ~100,000 edges) that is 33-42 ms against 4-5 ms here (docs/detector_features.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from negobs_gym.core.compiled import kernel
from negobs_gym.detector.pairs import close_pairs_within, range_scale
from negobs_gym.errors import GeometryError, require

_TINY = 1e-9  # sparse DBSCAN graphs drop explicit zeros: a zero distance is stored as this


@dataclass(frozen=True, kw_only=True)
class ClusteringConfig:
    """DBSCAN parameters (paper N §3.3 step 3) and the outline of degenerate clusters."""

    eps_m: float = 0.40  # T_dbscan, paper N §3.3: 40 cm
    min_pairs: int = 4  # MinFPs, paper N §3.3 (the pair itself counts, as in Tab. 4)
    # A pair farther than this from the vehicle counts w = range / this toward MinFPs and reaches
    # w * eps (w at most max_pair_weight; documented deviation, the paper counts every pair once
    # within a fixed eps). A sensor's scan lines cross a pit at a lateral spacing that grows with
    # range (the side HDL-32s' lasers are 1.33 deg apart: 0.23 m at 10 m, 0.46 m at 20 m, past
    # eps), so a pit of a given width yields pairs ~ 1/range, spread wider than eps: the fixed
    # rule ends the side sensors' reach at ~14 m, against paper N Fig. 16. Every pair is still
    # confirmed by fusion (3 hits, §4.2) before it is clustered. inf = the paper's rule.
    full_weight_range_m: float = 10.0
    max_pair_weight: float = 2.0
    # a cluster whose points are collinear has no area; its outline is the segment widened by this
    degenerate_half_width_m: float = 0.05
    # "graph": DBSCAN from the neighbour list (fast); "sklearn": scikit-learn's DBSCAN on
    # the same precomputed graph (the reference: same labels, ~10x slower on dense frames)
    dbscan_backend: str = "graph"

    def __post_init__(self) -> None:
        require(self.dbscan_backend in ("graph", "sklearn"), "dbscan_backend", "must be 'graph' or 'sklearn'")
        require(math.isfinite(self.eps_m) and self.eps_m > 0, "eps_m", "must be finite and > 0")
        require(
            isinstance(self.min_pairs, int) and self.min_pairs >= 1, "min_pairs", "must be an integer >= 1"
        )
        require(self.full_weight_range_m > 0, "full_weight_range_m", "must be > 0 (inf: every pair counts 1)")
        require(
            math.isfinite(self.max_pair_weight) and self.max_pair_weight >= 1,
            "max_pair_weight",
            "must be finite and >= 1",
        )
        require(
            math.isfinite(self.degenerate_half_width_m) and self.degenerate_half_width_m > 0,
            "degenerate_half_width_m",
            "must be finite and > 0",
        )


@dataclass(frozen=True, eq=False)
class DetectedObstacle:
    """One detected negative obstacle in the vehicle frame.

    Attributes:
        outline_xy_m: (k, 2) convex outline, counter-clockwise, not closed.
        centre_xy_m: (2,) centroid of the outline.
        area_m2: area of the outline.
        n_pairs: number of feature pairs in the cluster.
        pair_indices: indices of those pairs in the clustered arrays.
    """

    outline_xy_m: np.ndarray
    centre_xy_m: np.ndarray
    area_m2: float
    n_pairs: int
    pair_indices: np.ndarray


def pair_weights(a_xy: np.ndarray, b_xy: np.ndarray, config: ClusteringConfig) -> np.ndarray:
    """What each pair counts toward MinFPs: 1 up to ``full_weight_range_m`` (midpoint distance
    from the vehicle origin), then range / ``full_weight_range_m``, at most ``max_pair_weight``."""
    return range_scale(a_xy, b_xy, config.full_weight_range_m, config.max_pair_weight)


def cluster_labels(a_xy: np.ndarray, b_xy: np.ndarray, config: ClusteringConfig) -> np.ndarray:
    """DBSCAN label per pair (-1 = noise) under paper N's overlap distance."""
    n = len(a_xy)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    weights = pair_weights(a_xy, b_xy, config)
    # a pair reaches eps_m times its weight: pairs farther apart need not be measured
    i, j, d = close_pairs_within(a_xy, b_xy, config.eps_m * float(weights.max()), config.eps_m * weights)
    # the neighbourhood widens with the same factor: distances are divided by the smaller weight
    d = d / np.minimum(weights[i], weights[j])
    keep = d <= config.eps_m
    i, j, d = i[keep], j[keep], d[keep]
    # tolerance: a weight sum equal to MinFPs up to rounding is a core pair
    sample_weight = weights * (1.0 + 1e-9)
    if config.dbscan_backend == "sklearn":
        return _sklearn_labels(i, j, d, sample_weight, config)
    return dbscan_labels(i, j, sample_weight, config.min_pairs)


def dbscan_labels(i: np.ndarray, j: np.ndarray, weights: np.ndarray, min_weight: float) -> np.ndarray:
    """DBSCAN label per point (-1 = noise), numbered as scikit-learn's DBSCAN numbers them.

    ``(i, j)``: every two points within eps of each other, both ways, each point with itself (a
    symmetric neighbour list); ``weights``: what each point counts toward ``min_weight`` (MinPts).
    A core point's neighbour weights reach ``min_weight``; clusters are the connected components of
    the core points; scikit-learn grows them one at a time from the lowest-indexed core point not
    yet labelled, so they are numbered by their lowest core index, and a border point (not core,
    with a core neighbour) gets the first cluster grown that reaches it: the lowest-numbered one
    among its core neighbours'.
    """
    n = len(weights)
    labels = np.full(n, -1, dtype=np.int64)
    core = np.bincount(i, weights=weights[j], minlength=n) >= min_weight
    core_idx = np.flatnonzero(core)
    if core_idx.size == 0:
        return labels
    both = core[i] & core[j]
    root = _component_roots(i[both], j[both], n)
    # each component's root is its lowest index, a core point: numbered in the order of the roots
    roots = np.unique(root[core_idx])
    number = np.empty(n, dtype=np.int64)
    number[roots] = np.arange(len(roots))
    labels[core_idx] = number[root[core_idx]]
    reach = ~core[i] & core[j]
    if reach.any():
        unset = np.iinfo(np.int64).max
        border = np.full(n, unset)
        np.minimum.at(border, i[reach], labels[j[reach]])
        labels[border != unset] = border[border != unset]
    return labels


@kernel
def _component_roots(i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """Per point of an n-point graph with edges (i, j), the lowest index of its connected
    component (union-find, each root linked under the lower one; an isolated point is its own).
    scipy's ``connected_components`` gives the same components and spent ~10x this in checking
    and converting the sparse graph (1.2 ms against 0.05 ms on a dense frame's 22,000 edges)."""
    root = np.arange(n)
    for e in range(i.size):
        a = i[e]
        while root[a] != a:
            root[a] = root[root[a]]
            a = root[a]
        b = j[e]
        while root[b] != b:
            root[b] = root[root[b]]
            b = root[b]
        if a < b:
            root[b] = a
        elif b < a:
            root[a] = b
    for k in range(n):  # roots have lower indices: one pass in index order flattens every path
        root[k] = root[root[k]]
    return root


def _sklearn_labels(
    i: np.ndarray, j: np.ndarray, d: np.ndarray, weights: np.ndarray, config: ClusteringConfig
) -> np.ndarray:
    """scikit-learn's DBSCAN on the precomputed graph of the edges (i, j, d), d <= eps."""
    from sklearn.cluster import DBSCAN  # here: scikit-learn (with scipy.stats) takes ~1.2 s to import

    n = len(weights)
    d = np.maximum(d, _TINY)
    graph = _csr(i, j, d, _row_value_order(i, d, j), n)
    dbscan = DBSCAN(eps=config.eps_m, min_samples=config.min_pairs, metric="precomputed")
    return dbscan.fit_predict(graph, sample_weight=weights).astype(np.int64)


def _csr(i: np.ndarray, j: np.ndarray, values: np.ndarray, order: np.ndarray, n: int) -> sparse.csr_matrix:
    """(n, n) CSR matrix of the edges (i, j, values), stored in ``order`` (which must group them by
    row i): built directly, without the sort and duplicate check of a COO conversion."""
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(i, minlength=n), out=indptr[1:])
    return sparse.csr_matrix((values[order], j[order], indptr), shape=(n, n))


def _narrow(rows: np.ndarray) -> np.ndarray:
    """Row indices as uint16 where they fit: a stable sort of them is then a radix sort."""
    return rows.astype(np.uint16) if rows.size and int(rows.max()) < 2**16 else rows


def _row_value_order(i: np.ndarray, d: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Order of the edges (i, j, d) by row i, then distance d, then column j.

    scikit-learn's neighbour search wants each row of a precomputed graph stored by increasing
    distance: it checks that in one vectorized pass, but sorts an unsorted graph with one argsort
    per row (~1,500 calls on a dense frame). Ties go by column, as scipy's COO -> CSR conversion
    and a stable sort by distance leave them. One sort by distance, a stable (radix, for 16-bit
    rows) sort by row, then the rare runs of equal (row, distance) by column: 3.5x faster than
    ``np.lexsort((j, d, i))`` on the dense frame's 96,000 edges, with the same result.
    """
    order = np.argsort(d)
    order = order[np.argsort(_narrow(i)[order], kind="stable")]
    ii, dd = i[order], d[order]
    tie = (ii[1:] == ii[:-1]) & (dd[1:] == dd[:-1])
    if tie.any():
        in_run = np.zeros(order.size, dtype=bool)
        in_run[1:] |= tie
        in_run[:-1] |= tie
        at = np.flatnonzero(in_run)
        run = np.cumsum(np.concatenate([[True], ~tie]))[at]
        order[at] = order[at][np.lexsort((j[order[at]], run))]
    return order


def _unique_rows(xy: np.ndarray) -> np.ndarray:
    """``np.unique(xy, axis=0)`` of (n, 2) finite points (sorted by x, then y), ~10x faster on the
    few dozen points of a cluster."""
    if len(xy) == 0:
        return xy.reshape(0, 2)
    s = xy[np.lexsort((xy[:, 1], xy[:, 0]))]
    new = np.ones(len(s), dtype=bool)
    new[1:] = (s[1:] != s[:-1]).any(axis=1)
    return s[new]


def convex_outline(points_xy: np.ndarray, half_width_m: float) -> np.ndarray:
    """Counter-clockwise convex hull of (n, 2) points, from the lowest-x (then lowest-y) vertex;
    collinear points give a ``half_width_m`` strip.

    The points count as collinear when their smaller singular value (about their mean) is at most
    1e-6 of the larger; the hull is Andrew's monotone chain, compiled (~50x faster than scipy's
    qhull on a cluster's few dozen points, which paid ~0.15 ms a call in set-up). Points on a hull
    edge are not vertices.
    """
    pts = _unique_rows(np.asarray(points_xy, dtype=np.float64))
    if len(pts) >= 3:
        vertices = np.empty(2 * len(pts), dtype=np.int64)
        k = _monotone_chain(pts, vertices)
        if k >= 3:
            return pts[vertices[:k]]
    centred = pts - pts.mean(axis=0)
    vt = np.linalg.svd(centred, full_matrices=False)[2] if len(pts) > 1 else np.eye(2)
    major = vt[0]
    normal = np.array([-major[1], major[0]])
    t = centred @ major
    lo = pts.mean(axis=0) + t.min() * major
    hi = pts.mean(axis=0) + t.max() * major
    w = half_width_m * normal
    return np.array([lo - w, hi - w, hi + w, lo + w])


_COLLINEAR_SINGULAR_RATIO = 1e-6  # smaller / larger singular value at or below which points are a segment


@kernel
def _monotone_chain(pts: np.ndarray, vertices: np.ndarray) -> int:
    """Hull of (k >= 3, 2) distinct points sorted by x, then y (Andrew's monotone chain): writes
    the hull's vertex indices counter-clockwise from ``pts[0]`` into ``vertices`` (room for 2k)
    and returns their count, or 0 when the points are collinear (see :func:`convex_outline`)."""
    k = pts.shape[0]
    mx = 0.0
    my = 0.0
    for i in range(k):
        mx += pts[i, 0]
        my += pts[i, 1]
    mx /= k
    my /= k
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for i in range(k):
        dx = pts[i, 0] - mx
        dy = pts[i, 1] - my
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    # eigenvalues of the 2 x 2 scatter matrix: the squared singular values of the centred points
    big = 0.5 * (sxx + syy + np.sqrt((sxx - syy) ** 2 + 4.0 * sxy * sxy))
    small = (sxx * syy - sxy * sxy) / big if big > 0 else 0.0
    ratio = _COLLINEAR_SINGULAR_RATIO
    if not small > ratio * ratio * max(big, 1e-24):
        return 0
    m = 0
    for lower in (True, False):
        floor = 2 if lower else m + 1
        for step in range(k if lower else k - 1):
            i = step if lower else k - 2 - step
            while m >= floor:
                a = vertices[m - 2]
                b = vertices[m - 1]
                cross = (pts[b, 0] - pts[a, 0]) * (pts[i, 1] - pts[a, 1]) - (pts[b, 1] - pts[a, 1]) * (
                    pts[i, 0] - pts[a, 0]
                )
                if cross > 0:
                    break
                m -= 1
            vertices[m] = i
            m += 1
    return m - 1  # the upper chain ends where the lower began


def polygon_area_centroid(poly: np.ndarray) -> tuple[float, np.ndarray]:
    """Area and centroid of a simple counter-clockwise polygon (shoelace formula)."""
    p = np.ascontiguousarray(poly, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
        raise GeometryError(f"poly: needs a (k >= 1, 2) array of vertices, got shape {p.shape}")
    area, cx, cy = _shoelace(p)
    if abs(area) < 1e-12:
        return 0.0, p.mean(axis=0)
    return abs(area), np.array([cx, cy])


@kernel
def _shoelace(p: np.ndarray) -> tuple[float, float, float]:
    """Signed area and centroid of the (k, 2) polygon ``p``; (0, 0, 0) for a zero area."""
    twice = 0.0
    sx = 0.0
    sy = 0.0
    k = p.shape[0]
    for m in range(k):
        x, y = p[m, 0], p[m, 1]
        xn, yn = p[(m + 1) % k, 0], p[(m + 1) % k, 1]
        cross = x * yn - xn * y
        twice += cross
        sx += (x + xn) * cross
        sy += (y + yn) * cross
    area = 0.5 * twice
    if area == 0.0:
        return 0.0, 0.0, 0.0
    return area, sx / (6.0 * area), sy / (6.0 * area)


def cluster_obstacles(a_m: np.ndarray, b_m: np.ndarray, config: ClusteringConfig) -> list[DetectedObstacle]:
    """Cluster pairs (vehicle-frame (n, 3) A and B points) into obstacles, nearest first."""
    a_xy = np.asarray(a_m, dtype=np.float64)[:, :2]
    b_xy = np.asarray(b_m, dtype=np.float64)[:, :2]
    labels = cluster_labels(a_xy, b_xy, config)
    obstacles = []
    for label in np.unique(labels[labels >= 0]):
        idx = np.flatnonzero(labels == label)
        outline = convex_outline(np.concatenate([a_xy[idx], b_xy[idx]]), config.degenerate_half_width_m)
        area, centre = polygon_area_centroid(outline)
        obstacles.append(DetectedObstacle(outline, centre, area, len(idx), idx))
    obstacles.sort(key=lambda ob: float(np.hypot(*ob.centre_xy_m)))
    return obstacles
