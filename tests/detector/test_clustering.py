import warnings

import numpy as np
import pytest
from sklearn.exceptions import EfficiencyWarning

from negobs_gym.detector.clustering import (
    ClusteringConfig,
    _row_value_order,
    cluster_labels,
    cluster_obstacles,
    convex_outline,
    dbscan_labels,
    pair_weights,
    polygon_area_centroid,
)
from negobs_gym.detector.pairs import close_pairs_within
from negobs_gym.errors import ConfigError, GeometryError


def _radial_pairs(x0: float, x1: float, y_a: float, y_b: float, n: int, z_b: float = -0.5):
    """n radial pairs spread over [x0, x1], A at y_a on the ground, B at y_b on the back wall."""
    x = np.linspace(x0, x1, n)
    a = np.stack([x, np.full(n, y_a), np.zeros(n)], axis=1)
    b = np.stack([x, np.full(n, y_b), np.full(n, z_b)], axis=1)
    return a, b


def test_two_separate_pits_give_two_clusters_with_their_outlines():
    a1, b1 = _radial_pairs(-0.5, 0.5, 8.0, 9.0, 20)
    a2, b2 = _radial_pairs(2.0, 3.0, 12.0, 13.0, 20)
    obstacles = cluster_obstacles(np.concatenate([a1, a2]), np.concatenate([b1, b2]), ClusteringConfig())
    assert len(obstacles) == 2
    near, far = obstacles  # nearest first
    assert near.n_pairs == far.n_pairs == 20
    assert near.area_m2 == pytest.approx(1.0)
    np.testing.assert_allclose(near.centre_xy_m, [0.0, 8.5], atol=1e-9)
    np.testing.assert_allclose(far.centre_xy_m, [2.5, 12.5], atol=1e-9)
    assert set(near.pair_indices.tolist()) == set(range(20))


def test_fewer_than_min_pairs_is_noise():
    a, b = _radial_pairs(-0.1, 0.1, 8.0, 9.0, 3)
    assert (cluster_labels(a[:, :2], b[:, :2], ClusteringConfig()) == -1).all()
    assert cluster_obstacles(a, b, ClusteringConfig()) == []
    # MinFPs = 4 counts the pair itself (paper N Tab. 4): four close pairs form a cluster
    a, b = _radial_pairs(-0.1, 0.1, 8.0, 9.0, 4)
    assert len(cluster_obstacles(a, b, ClusteringConfig())) == 1


def test_eps_separates_rows_of_pairs():
    # pairs 0.15 m apart sideways chain into one cluster at eps 0.40; at eps 0.10 each is alone
    a, b = _radial_pairs(0.0, 1.05, 8.0, 9.0, 8)
    (ob,) = cluster_obstacles(a, b, ClusteringConfig())
    assert ob.n_pairs == 8
    assert cluster_obstacles(a, b, ClusteringConfig(eps_m=0.10)) == []


def test_collinear_cluster_gets_a_thin_strip_outline():
    a, b = _radial_pairs(0.0, 0.0, 8.0, 9.0, 5)
    (ob,) = cluster_obstacles(a, b, ClusteringConfig(degenerate_half_width_m=0.05))
    assert ob.area_m2 == pytest.approx(0.1)  # 1 m long x 0.1 m wide
    outline = convex_outline(np.array([[0.0, 0.0]]), 0.05)
    assert outline.shape == (4, 2) and np.isfinite(outline).all()


def test_polygon_area_centroid_of_a_square():
    area, c = polygon_area_centroid(np.array([[0, 0], [2, 0], [2, 2], [0, 2]], dtype=float))
    assert area == pytest.approx(4.0)
    np.testing.assert_allclose(c, [1.0, 1.0])
    area, c = polygon_area_centroid(np.array([[1.0, 1.0], [3.0, 1.0]]))  # no area: the mean
    assert area == 0.0
    np.testing.assert_array_equal(c, [2.0, 1.0])


@pytest.mark.parametrize("poly", [np.empty((0, 2)), np.zeros((4, 3)), np.zeros(4)])
def test_polygon_area_centroid_names_a_wrong_shape(poly):
    with pytest.raises(GeometryError, match="poly"):
        polygon_area_centroid(poly)


def test_no_pairs():
    assert cluster_obstacles(np.empty((0, 3)), np.empty((0, 3)), ClusteringConfig()) == []


@pytest.mark.parametrize(
    "field, value",
    [("eps_m", 0.0), ("eps_m", np.nan), ("min_pairs", 0), ("min_pairs", 2.5), ("dbscan_backend", "hdbscan")],
)
def test_bad_config(field, value):
    with pytest.raises(ConfigError, match=field):
        ClusteringConfig(**{field: value})


def test_pairs_beyond_full_weight_range_count_more_and_reach_farther():
    # three pairs 0.5 m apart (the side HDL-32s' line spacing at ~20 m): noise at 8 m, where every
    # pair counts once within eps = 0.40 m; one cluster at 18 m, where each counts 1.8 and reaches
    # 0.72 m
    near_a, near_b = _radial_pairs(-0.5, 0.5, 8.0, 9.0, 3)
    far_a, far_b = _radial_pairs(-0.5, 0.5, 18.0, 19.0, 3)
    cfg = ClusteringConfig()
    assert (cluster_labels(near_a[:, :2], near_b[:, :2], cfg) == -1).all()
    labels = cluster_labels(far_a[:, :2], far_b[:, :2], cfg)
    assert (labels == 0).all()
    paper = ClusteringConfig(full_weight_range_m=float("inf"))  # the paper's fixed count and eps
    assert (cluster_labels(far_a[:, :2], far_b[:, :2], paper) == -1).all()
    np.testing.assert_allclose(pair_weights(far_a[:, :2], far_b[:, :2], cfg), 1.85, atol=0.01)
    far_a2, far_b2 = _radial_pairs(-0.5, 0.5, 40.0, 41.0, 2)
    assert pair_weights(far_a2[:, :2], far_b2[:, :2], cfg).max() == cfg.max_pair_weight


def test_dbscan_gets_its_graph_sorted_by_row_values():
    # scikit-learn re-sorts (one argsort per row) and warns when a precomputed graph's rows are not
    # stored by increasing distance
    rng = np.random.default_rng(3)
    a = np.stack([rng.uniform(-3, 3, 300), rng.uniform(5, 15, 300)], axis=1)
    b = a + np.array([0.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error", EfficiencyWarning)
        labels = cluster_labels(a, b, ClusteringConfig(dbscan_backend="sklearn"))
    assert labels.max() >= 0


def test_graph_dbscan_gives_scikit_learns_labels():
    # random pair fields at several eps / MinFPs / weightings: clusters numbered alike, border pairs
    # (not core, next to cores of several clusters) in the same cluster, noise alike
    rng = np.random.default_rng(6)
    n_multi = n_border = 0
    for _ in range(150):
        n = int(rng.integers(1, 250))
        a = rng.uniform(-6, 6, (n, 2)) + np.array([0.0, rng.uniform(0, 14)])
        b = a + rng.normal(0.0, 0.4, (n, 2))
        kw = {"eps_m": float(rng.uniform(0.2, 1.0)), "min_pairs": int(rng.integers(1, 8))}
        if rng.random() < 0.3:
            kw["full_weight_range_m"] = float("inf")
        graph = cluster_labels(a, b, ClusteringConfig(**kw))
        np.testing.assert_array_equal(
            graph, cluster_labels(a, b, ClusteringConfig(dbscan_backend="sklearn", **kw))
        )
        n_multi += graph.max() >= 1
        strict = cluster_labels(a, b, ClusteringConfig(**{**kw, "min_pairs": 10**6}))  # no cores: all noise
        assert (strict == -1).all()
        n_border += _has_border(a, b, graph, kw)
    assert n_multi >= 50 and n_border >= 20  # the comparison covered both


def _has_border(a, b, labels, kw):
    """True when some labelled pair is not core (its own weighted neighbourhood is below MinFPs)."""
    cfg = ClusteringConfig(**kw)
    w = pair_weights(a, b, cfg)
    i, j, d = close_pairs_within(a, b, cfg.eps_m * float(w.max()))
    close = d / np.minimum(w[i], w[j]) <= cfg.eps_m
    count = np.bincount(i[close], weights=w[j[close]] * (1 + 1e-9), minlength=len(a))
    return bool(((labels >= 0) & (count < cfg.min_pairs)).any())


def test_dbscan_labels_on_a_hand_made_graph():
    # 0-1-2 core chain, 3 core alone with 4; 5 borders both clusters, 6 is noise
    edges = [(0, 1), (1, 2), (0, 2), (3, 4), (2, 5), (3, 5)]
    i = np.array([e[0] for e in edges] + [e[1] for e in edges] + list(range(7)))
    j = np.array([e[1] for e in edges] + [e[0] for e in edges] + list(range(7)))
    labels = dbscan_labels(i, j, np.array([1.0, 1, 1, 1, 2, 0.5, 1]), min_weight=3.0)
    # weighted neighbourhoods: 0, 1: 3; 2: 3.5; 3: 3.5; 4: 3 (cores); 5: 2.5 (border); 6: 1 (noise)
    np.testing.assert_array_equal(labels, [0, 0, 0, 1, 1, 0, -1])
    # numbered by the lowest core index: 0 is a border of {3, 4}, so the {1, 2} cluster comes first
    edges = [(1, 2), (3, 4), (0, 4)]
    i = np.array([e[0] for e in edges] + [e[1] for e in edges] + list(range(5)))
    j = np.array([e[1] for e in edges] + [e[0] for e in edges] + list(range(5)))
    labels = dbscan_labels(i, j, np.array([0.5, 1, 1, 1.5, 1]), min_weight=2.0)
    np.testing.assert_array_equal(labels, [1, 0, 0, 1, 1])


def test_row_value_order_is_row_then_distance_then_column():
    rng = np.random.default_rng(4)
    i = rng.integers(0, 50, 2000)
    j = rng.integers(0, 50, 2000)
    d = rng.choice([1e-9, 0.1, 0.2, 0.3], 2000) + rng.choice([0.0, 1e-16, 1e-15], 2000)  # ties, near-ties
    for dist in (d, rng.uniform(1e-9, 0.4, 2000)):  # and without ties, where one key sort is exact
        order, exact = _row_value_order(i, dist, j), np.lexsort((j, dist, i))
        for v in (i, dist, j):
            np.testing.assert_array_equal(v[order], v[exact])


def test_unique_rows_is_numpys_unique_by_rows():
    from negobs_gym.detector.clustering import _unique_rows

    rng = np.random.default_rng(5)
    xy = rng.integers(-3, 3, (200, 2)).astype(float)  # many duplicates
    xy[0] = [-0.0, 1.0]
    xy[1] = [0.0, 1.0]  # -0.0 and 0.0 are one point, as for np.unique
    for pts in (xy, rng.uniform(-1, 1, (50, 2)), np.empty((0, 2))):
        np.testing.assert_array_equal(_unique_rows(pts), np.unique(pts, axis=0))


def test_convex_outline_is_scipys_hull_counter_clockwise_from_the_lowest_x_vertex():
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(7)
    for n in (3, 4, 10, 60, 250):
        for scale in ((1.0, 1.0), (5.0, 0.02), (0.01, 3.0)):
            pts = rng.normal(size=(n, 2)) * scale + rng.uniform(-20, 20, size=2)
            outline = convex_outline(np.concatenate([pts, pts[:2]]), 0.05)  # duplicates are dropped
            assert {tuple(v) for v in outline} == {tuple(v) for v in pts[ConvexHull(pts).vertices]}
            x, y = outline[:, 0], outline[:, 1]
            assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0
            np.testing.assert_array_equal(outline[0], min(map(tuple, outline)))


def test_points_on_a_hull_edge_are_not_vertices_and_a_near_segment_is_a_strip():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0], [1, 0.25], [0.5, 0.5]], dtype=float)
    np.testing.assert_array_equal(convex_outline(square, 0.05), [[0, 0], [1, 0], [1, 1], [0, 1]])
    x = np.linspace(0.0, 2.0, 9)
    segment = np.stack([x, 3.0 + 1e-9 * np.sin(7 * x)], axis=1)  # width/length ~ 1e-9 < 1e-6
    outline = convex_outline(segment, 0.05)
    assert outline.shape == (4, 2)
    assert polygon_area_centroid(outline)[0] == pytest.approx(2.0 * 0.1)
    wide = np.stack([x, 3.0 + 1e-3 * np.sin(7 * x)], axis=1)  # 1e-3: a thin polygon, not a strip
    assert polygon_area_centroid(convex_outline(wide, 0.05))[0] < 0.01
