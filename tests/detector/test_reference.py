"""The detector's vectorized stages against straightforward reference computations, bit for bit.

The references are the plain formulations (whole-image numpy passes, all-pairs distances, a
general max filter): the block-wise, sparse and bounded code paths must give the same arrays,
and the detector run on the references must give the same Detection.
"""

import math

import numpy as np
import pytest
from scipy.ndimage import maximum_filter1d
from scipy.spatial import ConvexHull

from negobs_gym.core import GridSpec, Pose
from negobs_gym.detector import (
    NegativeObstacleDetector,
    clustering,
    fusion,
    hdl32,
    hdl64,
    negative,
    roi,
)
from negobs_gym.detector import pairs as pair_search
from negobs_gym.detector.blocks import BLOCK_ELEMENTS
from negobs_gym.detector.grid import convex_overlap_mask
from negobs_gym.detector.pair_test import pair_test
from negobs_gym.detector.pairs import FeaturePairs, close_pairs, close_pairs_within, overlap_distance
from negobs_gym.detector.synthetic import Block, Hole, hdl32_side_scan, hdl64_scan

# ---- references -------------------------------------------------------------------------------


def ref_max_filter(r, radius):
    filled = np.where(np.isnan(r), -np.inf, r)
    out = maximum_filter1d(filled, size=2 * radius + 1, axis=1, mode="nearest")
    return np.where(np.isnan(r), np.nan, out)


def ref_edge_labels(r, rise_m, fall_m, h):
    n_l, n_c = r.shape
    rp = np.concatenate([np.full((n_l, h), np.nan), r, np.full((n_l, h), np.nan)], axis=1)
    best = np.zeros(r.shape)
    with np.errstate(invalid="ignore"):
        for j in range(1, h + 1):
            for d in (rp[:, h + j : h + j + n_c] - r, r - rp[:, h - j : h - j + n_c]):
                np.copyto(best, d, where=np.abs(d) > np.abs(best))
    labels = np.zeros(r.shape, dtype=np.int8)
    labels[best > rise_m] = hdl64.RISE
    labels[best < fall_m] = hdl64.FALL
    return labels


def ref_find_bumps(labels):
    n_l, n_c = labels.shape
    idx = np.broadcast_to(np.arange(n_c), labels.shape)
    last_rise = np.maximum.accumulate(np.where(labels == hdl64.RISE, idx, -1), axis=1)
    last_fall = np.maximum.accumulate(np.where(labels == hdl64.FALL, idx, -1), axis=1)
    prev_fall = np.concatenate([np.full((n_l, 1), -1), last_fall[:, :-1]], axis=1)
    row, end = np.nonzero((labels == hdl64.FALL) & (last_rise > prev_fall))
    return row, last_rise[row, end], end


def ref_point_density(points, rows, cols, radius, laser_window, column_window):
    n_l, n_c, _ = points.shape
    if rows.size == 0:
        return np.zeros(0)
    dm = np.concatenate([np.arange(-laser_window, 0), np.arange(1, laser_window + 1)])
    dk = np.arange(-column_window, column_window + 1)
    rr = rows[:, None, None] + dm[None, :, None]
    cc = cols[:, None, None] + dk[None, None, :]
    inside = (rr >= 0) & (rr < n_l) & (cc >= 0) & (cc < n_c)
    nb = points[np.clip(rr, 0, n_l - 1), np.clip(cc, 0, n_c - 1)]
    dist = np.linalg.norm(nb - points[rows, cols][:, None, None, :], axis=-1)
    with np.errstate(invalid="ignore"):
        near = inside & (dist <= radius[:, None, None])
    return 1.0 + near.any(axis=2).sum(axis=1)


def ref_trace_pairs(points, valid, azimuth, rows, cols, epsilon):
    n_l, nb = points.shape[0], rows.size
    if nb == 0:
        return np.empty((0, 3)), np.empty((0, 3))
    az_b = azimuth[cols]
    tol = epsilon * (1 + 1e-9) + 1e-12
    lo = np.searchsorted(azimuth, az_b - tol, side="left")
    hi = np.searchsorted(azimuth, az_b + tol, side="right")
    win = lo[:, None] + np.arange(int((hi - lo).max()))[None, :]
    in_win = win < hi[:, None]
    win = np.minimum(win, azimuth.size - 1)
    cost = np.where(valid[:, win] & in_win[None], np.abs(azimuth[win] - az_b[:, None])[None], np.inf)
    best_col, has = cost.argmin(axis=2), np.isfinite(cost.min(axis=2))
    laser = np.arange(n_l)[:, None]
    below, above = has & (laser < rows[None, :]), has & (laser > rows[None, :])
    a_row = np.where(below.any(axis=0), np.where(below, laser, -1).max(axis=0), -1)
    c_row = np.where(above.any(axis=0), np.where(above, laser, n_l).min(axis=0), -1)
    out = []
    for r in (a_row, c_row):
        rr = np.where(r >= 0, r, 0)
        p = points[rr, win[np.arange(nb), best_col[rr, np.arange(nb)]]]
        out.append(np.where((r >= 0)[:, None], p, np.nan))
    return out[0], out[1]


def ref_compensate_missing(r):
    n_l, n_c = r.shape
    if n_c < 3 or n_l < 2:
        return r.copy()
    up = np.concatenate([r[1:], np.full((1, n_c), np.nan)])
    dn = np.concatenate([np.full((1, n_c), np.nan), r[:-1]])
    est = np.where(np.isnan(up), dn, np.where(np.isnan(dn), up, 0.5 * (up + dn)))
    left = np.concatenate([np.full((n_l, 1), np.nan), r[:, :-1]], axis=1)
    right = np.concatenate([r[:, 1:], np.full((n_l, 1), np.nan)], axis=1)
    lo, hi = np.fmin(left, right), np.fmax(left, right)
    with np.errstate(invalid="ignore"):
        ordered = (est >= lo) & (est <= hi)
    return np.where(np.isnan(r) & ordered, est, r)


def ref_extract_hdl32_pairs(scan, config):
    """Whole-image range jumps of the compensated scan, then the module's per-jump steps."""
    h = hdl64.sensor_height(scan, config.sensor_height_m)
    if scan.ranges_m.size == 0 or np.isnan(scan.ranges_m).all():
        return FeaturePairs.empty(scan.sensor)
    pts, valid = scan.points_vehicle, scan.valid
    r_c = ref_compensate_missing(scan.ranges_m) if config.compensate_missing else scan.ranges_m
    ground = hdl32.ground_hit_distance(scan, h)
    abc = [], [], []
    for step in (1, -1):
        rows, cols = np.nonzero(hdl32.range_jumps(r_c, ground, config.jump_threshold_m, step) & valid)
        dens = hdl32.same_laser_density(pts, config.density_radius_m, config.density_half_window, rows, cols)
        dense = dens > hdl32.density_threshold(pts[rows, cols], scan.translation_m, config)
        rows, cols = rows[dense], cols[dense]
        ok = (cols - step >= 0) & (cols - step < scan.ranges_m.shape[1])
        rows, cols = rows[ok], cols[ok]
        abc[0].append(pts[rows, cols - step])
        abc[1].append(pts[rows, cols])
        m, w = config.c_min_separation_m, config.density_half_window
        abc[2].append(hdl32.next_point(pts, rows, cols, step, m, w))
    a, b, c = (np.concatenate(x) for x in abc)
    ok = pair_test(a, b, c, scan.translation_m, h, config.pair_test)
    return FeaturePairs(scan.sensor, a[ok], b[ok], c[ok])


def _unit(x, y):
    n = np.sqrt(x * x + y * y)
    safe = np.where(n > 0, n, 1.0)
    return np.where(n > 0, x / safe, 1.0), np.where(n > 0, y / safe, 0.0)


def ref_overlap_distance(a1, b1, a2, b2):
    """The module docstring's definition, on whole (n, 2) arrays."""
    norm = lambda v: np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1])  # noqa: E731
    u1, u2 = np.stack(_unit(*(b1 - a1).T), 1), np.stack(_unit(*(b2 - a2).T), 1)
    sign = np.where((u1 * u2)[:, 0] + (u1 * u2)[:, 1] < 0.0, -1.0, 1.0)[:, None]
    axis = np.stack(_unit(*(u1 + sign * u2).T), 1)
    t = [p[:, 0] * axis[:, 0] + p[:, 1] * axis[:, 1] for p in (a1, b1, a2, b2)]
    lo = np.maximum(np.minimum(t[0], t[1]), np.minimum(t[2], t[3]))
    hi = np.minimum(np.maximum(t[0], t[1]), np.maximum(t[2], t[3]))

    def at(a, b, ta, tb, tt):
        span = tb - ta
        s = np.divide(tt - ta, span, out=np.full_like(tt, 0.5), where=np.abs(span) > 1e-12)
        return a + np.clip(s, 0.0, 1.0)[:, None] * (b - a)

    gaps = [norm(at(a1, b1, t[0], t[1], tt) - at(a2, b2, t[2], t[3], tt)) for tt in (lo, hi)]
    ends = [norm(p - q) for p in (a1, b1) for q in (a2, b2)]
    nearest = np.minimum(np.minimum(ends[0], ends[1]), np.minimum(ends[2], ends[3]))
    return np.where(hi >= lo, 0.5 * (gaps[0] + gaps[1]), nearest)


def ref_close_pairs(a1, b1, a2, b2, max_distance_m):
    """Every pair of pairs measured (``max_distance_m``: one value or one per pair of set 2)."""
    i, j = (g.ravel() for g in np.meshgrid(np.arange(len(a1)), np.arange(len(a2)), indexing="ij"))
    d = ref_overlap_distance(a1[i], b1[i], a2[j], b2[j])
    close = d <= (max_distance_m if np.ndim(max_distance_m) == 0 else np.asarray(max_distance_m)[j])
    return i[close], j[close], d[close]


def _c_atan2(y, x):
    """The C library's atan2, element by element: the map's per-point rule on every machine (numpy's
    arctan2 is its own SIMD routine on AVX-512 CPUs, which can differ in the last bit)."""
    return np.frompyfunc(math.atan2, 2, 1)(y, x).astype(np.float64)


def ref_ground_cells(clouds, max_range_m, config):
    """Lowest and highest z per polar cell, one cloud at a time as a whole."""
    n_sectors = int(np.ceil(360.0 / config.sector_deg))
    n_bins = max(1, int(np.ceil((max_range_m + config.range_margin_m) / config.bin_m)))
    z_min, z_max = np.full(n_sectors * n_bins, np.inf), np.full(n_sectors * n_bins, -np.inf)
    for cloud in clouds:
        p = cloud.reshape(-1, 3)
        with np.errstate(invalid="ignore"):
            p = p[np.isfinite(p[:, 2]) & (p[:, 0] ** 2 + p[:, 1] ** 2 < (n_bins * config.bin_m) ** 2)]
        dist = np.sqrt(p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1])
        sector = np.floor((_c_atan2(p[:, 1], p[:, 0]) + np.pi) / np.radians(config.sector_deg))
        cell = (sector.astype(np.int64) % n_sectors) * n_bins + np.minimum(
            (dist / config.bin_m).astype(np.int64), n_bins - 1
        )
        np.minimum.at(z_min, cell, p[:, 2])
        np.maximum.at(z_max, cell, p[:, 2])
    return z_min.reshape(n_sectors, n_bins), z_max.reshape(n_sectors, n_bins)


def ref_ground_level(z_min, config):
    """Ground level walking each sector outward, one cell at a time."""
    slope = np.tan(np.radians(config.max_ground_slope_deg))
    ground = np.zeros_like(z_min)
    for s in range(z_min.shape[0]):
        z_g = d_g = 0.0
        for k in range(z_min.shape[1]):
            d_k, low = (k + 0.5) * config.bin_m, z_min[s, k]
            rise = slope * (d_k - d_g)
            if (
                np.isfinite(low)
                and low <= z_g + config.ground_step_m + rise
                and low >= z_g - config.ground_step_m - slope * config.bin_m
            ):
                z_g, d_g = low, d_k
            ground[s, k] = z_g
    return ground


# ---- stage by stage ---------------------------------------------------------------------------


def _range_images(rng):
    """Random range images with steps, single spikes, NaN runs and rows shorter than the windows."""
    images = []
    for n_l, n_c in ((5, 0), (3, 1), (4, 2), (4, 3), (6, 7), (8, 50), (9, 3000)):
        r = 5.0 + np.cumsum(rng.choice([0.0, 0.0, 0.0, 0.25, -0.25, 0.6, -0.6], size=(n_l, n_c)), axis=1)
        r += rng.normal(0, 0.05, r.shape)
        r[rng.random(r.shape) < 0.1] = np.nan
        images.append(r)
        images.append(np.round(r * 4) / 4)  # exact ties between candidate differences
    return images


def test_max_filter_edges_and_bumps_match_the_whole_image_references():
    for r in _range_images(np.random.default_rng(0)):
        for radius in (1, 3, 4):
            np.testing.assert_array_equal(hdl64.max_filter_ranges(r, radius), ref_max_filter(r, radius))
        for half in (1, 2, 3):
            for rise, fall in ((0.2, -0.2), (0.1, -0.4)):
                labels = hdl64.edge_labels(r, rise, fall, half)
                np.testing.assert_array_equal(labels, ref_edge_labels(r, rise, fall, half))
                for got, want in zip(hdl64.find_bumps(labels), ref_find_bumps(labels), strict=True):
                    np.testing.assert_array_equal(got, want)


def test_missing_return_compensation_matches_the_whole_image_reference():
    for r in _range_images(np.random.default_rng(8)):
        np.testing.assert_array_equal(hdl32.compensate_missing(r), ref_compensate_missing(r))


@pytest.fixture(scope="module")
def pit_scan():
    holes = [Hole.ahead(8.0, 1.0, 1.0, 0.8), Hole.ahead(13.0, 1.5, 0.6, 0.8)]
    return hdl64_scan(holes, noise_sigma_m=0.02, rng=np.random.default_rng(1))


def test_density_and_ray_tracing_match_the_references_on_a_scan(pit_scan):
    pts, valid = pit_scan.points_vehicle, pit_scan.valid
    rng = np.random.default_rng(2)
    rows, cols = np.nonzero(valid)
    pick = rng.choice(rows.size, 3000, replace=False)  # several blocks of query points
    rows, cols = rows[pick], cols[pick]
    radius = rng.uniform(0.05, 0.6, rows.size)
    for lw, cw in ((6, 2), (1, 0), (3, 4)):
        np.testing.assert_array_equal(
            hdl64.point_density(pts, rows, cols, radius, lw, cw),
            ref_point_density(pts, rows, cols, radius, lw, cw),
        )
    for eps_deg in (0.0, 0.09, 0.5):
        eps = np.radians(eps_deg)
        got = hdl64.trace_pairs(pts, valid, pit_scan.azimuth_rad, rows, cols, eps)
        want = ref_trace_pairs(pts, valid, pit_scan.azimuth_rad, rows, cols, eps)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)


def _random_pairs(rng, n):
    a = rng.uniform(-4, 4, (n, 2))
    b = a + rng.normal(0, 0.6, (n, 2))
    b[: n // 10] = a[: n // 10]  # zero-length pairs
    b[n // 10 : n // 5] = a[n // 10 : n // 5] + np.array([0.0, 0.7])  # exactly parallel pairs
    return a, b


def test_overlap_distance_matches_the_definition_and_is_symmetric_bit_for_bit():
    rng = np.random.default_rng(4)
    a1, b1 = _random_pairs(rng, 20000)  # more rows than a block
    a2, b2 = _random_pairs(rng, 20000)
    d = overlap_distance(a1, b1, a2, b2)
    np.testing.assert_array_equal(d, ref_overlap_distance(a1, b1, a2, b2))
    np.testing.assert_array_equal(overlap_distance(a2, b2, a1, b1), d)  # close_pairs_within relies on it


@pytest.mark.parametrize("one_class_max_pairs", [None, 0], ids=["default", "length_classes"])
def test_close_pairs_find_exactly_the_pairs_all_pairs_measuring_finds(monkeypatch, one_class_max_pairs):
    # the default puts these few hundred pairs in one length class; 0 splits them by length
    if one_class_max_pairs is not None:
        monkeypatch.setattr(pair_search, "_ONE_CLASS_MAX_PAIRS", one_class_max_pairs)
    rng = np.random.default_rng(5)
    a1, b1 = _random_pairs(rng, 300)
    a2, b2 = _random_pairs(rng, 250)
    for max_d in (0.1, 0.4, 0.8):
        want = sorted(zip(*(v.tolist() for v in ref_close_pairs(a1, b1, a2, b2, max_d)), strict=True))
        got = sorted(zip(*(v.tolist() for v in close_pairs(a1, b1, a2, b2, max_d)), strict=True))
        assert got == want and want
        want = sorted(zip(*(v.tolist() for v in ref_close_pairs(a1, b1, a1, b1, max_d)), strict=True))
        got = sorted(zip(*(v.tolist() for v in close_pairs_within(a1, b1, max_d)), strict=True))
        assert got == want
        # per-pair limits: every pair within both limits is kept, none is invented
        limit = rng.uniform(0.3, 1.0, len(a1)) * max_d
        got = set(zip(*(v.tolist() for v in close_pairs_within(a1, b1, max_d, limit)), strict=True))
        assert got <= set(want)
        assert {(i, j, d) for i, j, d in want if d <= min(limit[i], limit[j])} <= got
        assert len(got) < len(want)  # the limits do leave pairs out


def test_ground_map_matches_the_cell_by_cell_reference(pit_scan):
    config = roi.RoiConfig()
    car = hdl64_scan([], blocks=[Block(x0_m=3.0, x1_m=5.0, y0_m=-2.0, y1_m=2.0, height_m=1.5)], n_columns=900)
    clouds = [pit_scan.points_vehicle, hdl32_side_scan([], side="left").points_vehicle, car.points_vehicle]
    assert clouds[0].size // 3 > BLOCK_ELEMENTS  # binned in several blocks
    gm = roi.build_ground_map(clouds, 20.0, config)
    z_min, z_max = ref_ground_cells(clouds, 20.0, config)
    ground = ref_ground_level(z_min, config)
    np.testing.assert_array_equal(gm.ground_z_m, ground)
    structure = z_max > ground + config.ground_tolerance_m
    assert structure.any()
    np.testing.assert_array_equal(gm.structure_before[:, 1:], np.cumsum(structure, axis=1))


# ---- end to end -------------------------------------------------------------------------------


def _frames():
    holes = [Hole.ahead(float(y), 1.0, 1.0, 0.8) for y in (7.0, 11.0)]
    holes += [Hole(x0_m=2.0, x1_m=3.0, y0_m=9.0, y1_m=10.0, depth_m=0.8)]
    blocks = [Block(x0_m=-4.0, x1_m=-3.0, y0_m=8.0, y1_m=12.0, height_m=1.6)]
    rng = np.random.default_rng(7)
    kw = {"blocks": blocks, "noise_sigma_m": 0.02, "rng": rng}
    return [
        (
            {
                "hdl64": hdl64_scan(holes, **kw),
                "hdl32_left": hdl32_side_scan(holes, side="left", **kw),
                "hdl32_right": hdl32_side_scan(holes, side="right", **kw),
            },
            Pose(x=0.01 * k, y=0.05 * k, z=0.0, roll=0.0, pitch=0.0, yaw=0.002 * k),
        )
        for k in range(4)
    ]


def _ref_close_pairs_within(a, b, max_distance_m, limit_m=None):
    return ref_close_pairs(a, b, a, b, max_distance_m)  # no pair left out: a superset of the limits


def test_detector_on_the_references_gives_the_same_detection_bit_for_bit(monkeypatch):
    frames = _frames()
    detector = NegativeObstacleDetector()
    fast = [detector.update(scans, pose) for scans, pose in frames]
    for module, name, ref in (
        (hdl64, "max_filter_ranges", ref_max_filter),
        (hdl64, "edge_labels", ref_edge_labels),
        (hdl64, "find_bumps", ref_find_bumps),
        (hdl64, "point_density", ref_point_density),
        (hdl64, "trace_pairs", ref_trace_pairs),
        (fusion, "close_pairs", ref_close_pairs),
        (clustering, "close_pairs_within", _ref_close_pairs_within),
        (negative, "extract_hdl32_pairs", ref_extract_hdl32_pairs),
    ):
        monkeypatch.setattr(module, name, ref)
    detector = NegativeObstacleDetector()
    slow = [detector.update(scans, pose) for scans, pose in frames]
    assert sum(len(d.obstacles) for d in fast) >= 3  # the scene is detected, not empty
    for f, s in zip(fast, slow, strict=True):
        for name in f.frame_pairs:
            for field in ("a_m", "b_m", "c_m"):
                got, want = getattr(f.frame_pairs[name], field), getattr(s.frame_pairs[name], field)
                np.testing.assert_array_equal(got, want)
        for field in ("a_m", "b_m", "posterior", "confirmed"):
            np.testing.assert_array_equal(getattr(f.pairs, field), getattr(s.pairs, field))
        np.testing.assert_array_equal(f.grid, s.grid)
        assert len(f.obstacles) == len(s.obstacles)
        for p, q in zip(f.obstacles, s.obstacles, strict=True):
            np.testing.assert_array_equal(p.outline_xy_m, q.outline_xy_m)
            np.testing.assert_array_equal(p.pair_indices, q.pair_indices)


class RefPairFusion(fusion.PairFusion):
    """Fusion as paper N §3.3 states it: each sensor's pairs matched in turn against the history
    grown by the sensors before it (one all-pairs search per sensor)."""

    def update(self, pairs, pose):
        cfg = self.config
        a_v, b_v = pose.to_vehicle(self._a_w), pose.to_vehicle(self._b_w)
        p, age = self._p.copy(), self._age + 1
        matched = np.zeros(len(p), dtype=bool)
        for sensor, fp in pairs.items():
            reach = np.full(len(fp), cfg.match_distance_m)
            if sensor in cfg.range_scaled_sensors:
                reach *= fusion.range_scale(fp.a_m, fp.b_m, cfg.match_full_range_m, cfg.max_match_scale)
            d = np.full((len(p), len(fp)), np.inf)
            i, j, dist = ref_close_pairs(a_v[:, :2], b_v[:, :2], fp.a_m[:, :2], fp.b_m[:, :2], np.inf)
            d[i, j] = dist
            hit = (d <= reach[None, :]).any(axis=1)
            p[hit] = fusion.bayes_hit(p[hit], cfg.likelihood(sensor))
            matched |= hit
            age[hit] = 0
            fresh = ~(d <= cfg.match_distance_m).any(axis=0)
            a_v, b_v = np.concatenate([a_v, fp.a_m[fresh]]), np.concatenate([b_v, fp.b_m[fresh]])
            p = np.concatenate(
                [p, fusion.bayes_hit(np.full(int(fresh.sum()), cfg.prior), cfg.likelihood(sensor))]
            )
            age = np.concatenate([age, np.zeros(int(fresh.sum()), dtype=np.int64)])
            matched = np.concatenate([matched, np.ones(int(fresh.sum()), dtype=bool)])
        p[~matched] = fusion.bayes_miss(p[~matched], cfg.likelihood("default"))
        keep = (p >= cfg.prune_posterior) & (age <= cfg.max_age_frames)
        a_v, b_v, p, age = a_v[keep], b_v[keep], p[keep], age[keep]
        self._a_w, self._b_w, self._p, self._age = pose.to_world(a_v), pose.to_world(b_v), p, age
        return fusion.FusedPairs(a_v, b_v, p, p >= cfg.confirm_posterior)


def test_fusion_matches_sensor_by_sensor_matching_bit_for_bit():
    # one search of the frame against the history plus small searches against the frame's new
    # pairs give what matching each sensor against the grown history gives
    detector = NegativeObstacleDetector()
    frames = [(detector.update(scans, pose).frame_pairs, pose) for scans, pose in _frames()]
    fast, slow = fusion.PairFusion(), RefPairFusion()
    n_fresh_seen = 0
    for pairs, pose in frames:
        n_before = len(fast)
        got, want = fast.update(pairs, pose), slow.update(pairs, pose)
        n_fresh_seen += len(got) > n_before
        for field in ("a_m", "b_m", "posterior", "confirmed"):
            np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
    assert got.confirmed.sum() >= 20 and n_fresh_seen >= 2


def test_overlap_mask_window_uses_the_grid_cell_centres():
    grid = GridSpec()
    rng = np.random.default_rng(9)
    for _ in range(20):
        centre = rng.uniform([-9.0, -4.0], [9.0, 29.0])
        poly = centre + rng.uniform(-1.5, 1.5, (6, 2))
        hull = poly[ConvexHull(poly).vertices]
        # reference: every cell of the grid tested against every edge's normal (separating axes)
        edge = np.roll(hull, -1, axis=0) - hull
        normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1)
        reach = 0.5 * grid.cell_m * np.abs(normal).sum(axis=1)
        separated = grid.cell_centres() @ normal.T - reach > np.einsum("kd,kd->k", normal, hull)
        # and the square's own axes: the cells from the one holding the outline's lowest corner to
        # the one holding its highest
        (r0, r1), (c0, c1), _ = grid.cell_of(np.stack([hull.min(axis=0), hull.max(axis=0)]))
        in_box = np.zeros(grid.shape, dtype=bool)
        in_box[max(r0, 0) : r1 + 1, max(c0, 0) : c1 + 1] = True
        np.testing.assert_array_equal(convex_overlap_mask(hull, grid), in_box & ~separated.any(axis=-1))
