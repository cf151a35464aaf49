"""Hough line, tear points and boundary points (paper T §3.1)."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.detector.traversable import TrackScene, TraversableConfig, synthetic_scan
from negobs_gym.detector.traversable.tears import (
    boundary_points,
    curve_inliers,
    hough_lines,
    line_frame,
    line_inliers,
    refine_curves,
    segment_end_indices,
    segment_ends,
)

CFG = TraversableConfig()


def test_hough_finds_a_tilted_line_among_clutter() -> None:
    rng = np.random.default_rng(0)
    x = np.linspace(-5, 5, 200)
    y = 8.0 + 0.2 * x  # x cos(phi) + y sin(phi) = rho
    clutter = rng.uniform([-10, 0], [10, 20], size=(40, 2))
    xy = np.concatenate([np.column_stack([x, y]), clutter])[None]
    phi, rho = hough_lines(xy, np.ones(xy.shape[:2], dtype=bool), CFG)
    expected_phi = np.pi / 2 + np.arctan(0.2)  # normal (-0.2, 1)
    assert phi[0] == pytest.approx(expected_phi, abs=np.radians(1.0))
    inl = line_inliers(xy, np.ones(xy.shape[:2], dtype=bool), phi, rho, CFG)
    assert inl[0, :200].all()
    assert inl[0, 200:].sum() < 10


def test_hough_layer_without_points_is_nan() -> None:
    xy = np.zeros((2, 5, 2))
    valid = np.array([[True] * 5, [False] * 5])
    phi, rho = hough_lines(xy, valid, CFG)
    assert np.isfinite(phi[0]) and np.isnan(phi[1]) and np.isnan(rho[1])


def test_segment_ends_skip_short_fragments_at_the_ends() -> None:
    x = np.concatenate([[-9.0, -8.9], np.arange(-4.0, 4.01, 0.1), [8.0, 8.1, 8.2]])
    pts = np.column_stack([x, np.full(x.size, 8.0)])
    left, right = segment_ends(pts, CFG)
    assert left == pytest.approx([-4.0, 8.0]) and right == pytest.approx([4.0, 8.0])


def test_segment_ends_need_n_clean_links() -> None:
    pts = np.column_stack([np.arange(CFG.clean_run_points) * 0.1, np.zeros(CFG.clean_run_points)])
    left, right = segment_ends(pts, CFG)  # n points have only n - 1 links
    assert np.isnan(left).all() and np.isnan(right).all()
    left, _ = segment_ends(np.vstack([pts, [[0.1 * CFG.clean_run_points, 0.0]]]), CFG)
    assert left == pytest.approx([0.0, 0.0])


def test_boundary_points_of_flat_lines_between_walls() -> None:
    # 3 boundary layers + a top layer: straight ground lines from x = -3 to 3, wall points beyond.
    cols = 121
    x = np.linspace(-6, 6, cols)
    pts = np.zeros((4, cols, 3))
    for layer, y in enumerate((9.0, 10.0, 11.5, 13.0)):
        pts[layer, :, 0] = np.clip(x, -3.0, 3.0)
        pts[layer, :, 1] = np.where(np.abs(x) <= 3.0, y, y - 2.0 * (np.abs(x) - 3.0))
    ranges = np.linalg.norm(pts - np.array([0.0, 3.7, 0.65]), axis=-1)
    left, right = boundary_points(pts, ranges, CFG)
    assert left.shape == (3, 2)
    assert np.allclose(left[:, 0], -3.0, atol=0.11) and np.allclose(right[:, 0], 3.0, atol=0.11)
    # Wall points within the line tolerance still count as on the line: y within that tolerance.
    assert np.allclose(left[:, 1], [9.0, 10.0, 11.5], atol=CFG.line_tolerance_m)


def _ground_lines_between_banks(cols: int = 81) -> tuple[np.ndarray, np.ndarray]:
    """4 layers: ground from x = -3 to 3 at y = 10, 11, 12, 13; bank points pulled in beyond.

    The bank pulls a point 2 m nearer per metre beyond the edge, so the first bank points stay
    within the 0.6 m tolerance: segments end on the bank foot, 0.3-0.4 m beyond the edge.
    """
    x = np.linspace(-4, 4, cols)
    pts = np.zeros((4, cols, 3))
    pts[..., 0] = x
    beyond = np.maximum(np.abs(x) - 3.0, 0.0)
    pts[..., 1] = 10.0 + np.arange(4)[:, None] - 2.0 * beyond
    return pts, x


def _ranges(pts: np.ndarray) -> np.ndarray:
    return np.linalg.norm(pts - np.array([0.0, 3.7, 0.65]), axis=-1)


def _on_bank_foot(point: np.ndarray, layer: int) -> bool:
    beyond = abs(point[0]) - 3.0
    return 0.0 <= beyond <= 0.45 and point[1] == pytest.approx(10.0 + layer - 2.0 * beyond)


def test_segment_end_at_an_occluder_is_not_a_boundary_point() -> None:
    # Layer 0's columns right of x = 1 hit a pole at y = 8 instead of the ground.
    pts, x = _ground_lines_between_banks()
    pts[0, x > 1.0, 1] = 8.0
    left, right = boundary_points(pts, _ranges(pts), CFG)
    assert np.isnan(right[0]).all()  # ends at the occluder: missing, not a road edge
    assert _on_bank_foot(right[1], 1) and right[1][0] > 0
    assert _on_bank_foot(left[0], 0) and left[0][0] < 0


def test_segment_end_at_the_edge_of_the_field_of_view_is_not_a_boundary_point() -> None:
    # Layer 0 sees only x <= 2.5: its scan line is still on the ground when the FOV ends, so
    # its right end is no road edge (taking it would put the boundary on the FOV's edge ray).
    pts, x = _ground_lines_between_banks()
    pts[0, x > 2.5] = np.nan
    left, right = boundary_points(pts, _ranges(pts), CFG)
    assert np.isnan(right[0]).all()
    assert _on_bank_foot(left[0], 0) and left[0][0] < 0
    assert _on_bank_foot(right[1], 1) and right[1][0] > 0
    # One return beyond the end (here the floor of a drop-off) makes the same end a tear again.
    pts[0, -1] = [4.0, 12.0, -1.0]
    _, right = boundary_points(pts, _ranges(pts), CFG)
    assert right[0] == pytest.approx([2.5, 10.0])


def test_scan_lines_over_110_deg_are_conics_and_the_parabola_refit_follows_them() -> None:
    # Flat ground in the whole FOV. A straight line misses the ends of the lowest layer by ~0.5 m
    # towards the sensor and those of the upper layers away from it; the parabola stays within
    # a few centimetres everywhere, so the tolerance band means the same at every azimuth.
    scan = synthetic_scan(TrackScene(left_half_width_m=40.0, right_half_width_m=40.0))
    xy = scan.points_vehicle[:3, :, :2]
    valid = np.isfinite(xy).all(axis=-1)
    assert valid.all()
    phi, _ = hough_lines(xy, valid, CFG)
    u, v = line_frame(xy, phi)
    coef = refine_curves(u, v, valid, CFG)
    parabola = coef[:, :1] + coef[:, 1:2] * u + coef[:, 2:] * u * u
    assert np.abs(v - parabola).max() < 0.06
    line_end_residual = []
    for layer in range(3):
        line = np.polyfit(u[layer], v[layer], 1)
        res = v[layer] - np.polyval(line, u[layer])
        line_end_residual.append(0.5 * (res[0] + res[-1]))
    towards_sensor = np.sign(np.mean(v[0])) * np.array(line_end_residual)  # v grows away from it
    assert towards_sensor[0] < -0.3 and towards_sensor[2] > 0.2
    # With the parabola every column of every layer is on the scan line.
    assert curve_inliers(u, v, valid, coef, CFG).all()


def test_parabola_refit_needs_enough_points() -> None:
    u = np.tile(np.arange(8) * 0.5, (2, 1))
    v = 10.0 + 0.1 * u - 0.02 * u**2
    inliers = np.ones((2, 8), dtype=bool)
    inliers[1, CFG.curve_min_points - 1 :] = False
    coef = refine_curves(u, v, inliers, CFG)
    assert coef[0] == pytest.approx([10.0, 0.1, -0.02])
    assert np.isnan(coef[1]).all()  # fewer than curve_min_points inliers
    # All points at one along-line position span no parabola; NaN points are never used.
    assert np.isnan(refine_curves(np.zeros((1, 8)), v[:1], np.ones((1, 8), dtype=bool), CFG)).all()
    u_nan = u[:1].copy()
    u_nan[0, 0] = np.nan
    assert refine_curves(u_nan, v[:1], np.ones((1, 8), dtype=bool), CFG)[0] == pytest.approx(
        [10.0, 0.1, -0.02]
    )


def segment_ends_reference(points_xy: np.ndarray, config: TraversableConfig) -> tuple[int, int] | None:
    """Walk in from each end: the first index followed by n links no longer than the tear distance."""
    n = config.clean_run_points
    gaps = [float(np.linalg.norm(points_xy[i + 1] - points_xy[i])) for i in range(len(points_xy) - 1)]
    clean = [i for i in range(len(gaps) - n + 1) if all(g <= config.tear_distance_m for g in gaps[i : i + n])]
    return (clean[0], clean[-1] + n) if clean else None


def test_all_layers_segment_ends_match_each_layer_walked_alone() -> None:
    # boundary_points finds every layer's ends in one chained pass; the links between layers must
    # not join two layers' runs (the last points of one layer lie next to the first of the next).
    from negobs_gym.detector.traversable.tears import _layer_segment_ends

    rng = np.random.default_rng(5)
    for _ in range(40):
        layers, cols = 3, int(rng.integers(0, 30))
        steps = rng.choice([0.1, 0.3, 0.7], size=layers * cols, p=[0.6, 0.25, 0.15])
        x = np.cumsum(steps).reshape(layers, cols)  # each layer goes on where the last one ended
        xy = np.stack([x, np.zeros_like(x)], axis=-1)
        inliers = rng.random((layers, cols)) < 0.8
        got = _layer_segment_ends(xy, inliers, CFG)
        for i in range(layers):
            cols_i = np.flatnonzero(inliers[i])
            ref = segment_ends_reference(xy[i, cols_i], CFG)
            assert got[i] == (None if ref is None else (int(cols_i[ref[0]]), int(cols_i[ref[1]])))
            assert segment_end_indices(xy[i, cols_i], CFG) == ref


def test_condition_test_agrees_with_numpy_cond() -> None:
    # The parabola fit's shortcut (a trace^3 / det bound, SVD only where it is inconclusive) must
    # accept exactly the normal-equation matrices np.linalg.cond accepts, ill-conditioned ones too.
    from negobs_gym.detector.traversable.tears import _MAX_CONDITION, _well_conditioned

    rng = np.random.default_rng(3)
    mats = []
    for spread in (1.0, 1e-2, 1e-3, 3e-4, 1e-4, 3e-5, 1e-6, 0.0):
        for _ in range(25):
            u = rng.uniform(-1.0, 1.0, int(rng.integers(3, 60))) * spread + rng.uniform(-1.0, 1.0)
            p = np.stack([np.ones_like(u), u, u * u], axis=-1)
            mats.append(p.T @ p)
    ata = np.array(mats)
    expected = np.linalg.cond(ata) < _MAX_CONDITION
    assert 0 < expected.sum() < expected.size  # both outcomes occur
    assert np.array_equal(_well_conditioned(ata), expected)
