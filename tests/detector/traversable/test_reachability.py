"""Paper T Fig. 8 as tests: Eq. 12 (width) and Eq. 13 (turning radius) reachability."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.core import GridSpec
from negobs_gym.detector.traversable import BoundaryLine, ObstacleCluster, TraversableConfig
from negobs_gym.detector.traversable.reachability import (
    PathIndex,
    build_path_family,
    feasible_mask,
    reachable_mask,
)

GRID = GridSpec()
CENTRES = GRID.cell_centres()
LEFT = BoundaryLine(0.0, -9.0)
RIGHT = BoundaryLine(0.0, 7.3)


def disc(x: float, y: float, width: float) -> ObstacleCluster:
    a = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
    pts = np.column_stack([x + width / 2 * np.cos(a), y + width / 2 * np.sin(a), np.zeros(a.size)])
    return ObstacleCluster(points_m=pts, centre_xy_m=np.array([x, y]), width_m=width)


def scene(shift_y: float, config: TraversableConfig) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 8: obstacle A ahead-left (wide gap to its left), B ahead-right (narrow gap to its right)."""
    trav = (CENTRES[..., 1] >= -1.0) & (CENTRES[..., 1] <= 25.0)
    trav &= (CENTRES[..., 0] >= -9.0) & (CENTRES[..., 0] <= 7.3)
    obstacles = [disc(-2.5, 7.0 + shift_y, 2.5), disc(4.5, 9.0 + shift_y, 2.0)]
    feas = feasible_mask(CENTRES, trav, LEFT, RIGHT, obstacles, config)
    reach = reachable_mask(feas, build_path_family(GRID, config), exempt_below_y_m=0.0)
    return feas, reach


def gap_beside_a(shift_y: float) -> np.ndarray:
    return (CENTRES[..., 0] < -2.5 - 1.25 - 1.3) & (np.abs(CENTRES[..., 1] - 7.0 - shift_y) < 0.5)


def cell(x: float, y: float) -> tuple[int, int]:
    row, col, inside = GRID.cell_of(np.array([x, y]))
    assert inside
    return int(row), int(col)


def test_turn_radii_eq13() -> None:
    cfg = TraversableConfig()
    assert cfg.rear_turn_radius_m == pytest.approx(2.8 / math.tan(math.radians(35.0)))
    assert cfg.front_turn_radius_m == pytest.approx(2.8 / math.sin(math.radians(35.0)))
    assert cfg.front_turn_radius_m > cfg.rear_turn_radius_m


def test_gap_beside_a_wide_enough_but_unreachable_under_35_deg() -> None:
    cfg = TraversableConfig()
    feas, reach = scene(0.0, cfg)
    gap = gap_beside_a(0.0)
    assert feas[gap].sum() >= 20  # Eq. 12 holds: the gap is wide enough
    assert not reach[gap].any()  # ... but the turning radius does not allow getting there
    # Control: the same layout 8 m farther ahead leaves room to turn -> the gap becomes reachable.
    _feas_far, reach_far = scene(8.0, cfg)
    assert reach_far[gap_beside_a(8.0)].any()


def test_gap_beside_b_reachable_by_radius_but_narrower_than_vehicle() -> None:
    cfg = TraversableConfig()
    feas, reach = scene(0.0, cfg)
    # Between B (edge at x = 5.5) and the right boundary (x = 7.3): a 1.8 m gap.
    gap = (CENTRES[..., 0] > 5.7) & (CENTRES[..., 0] < 7.1) & (np.abs(CENTRES[..., 1] - 9.0) < 0.6)
    assert not feas[gap].any() and not reach[gap].any()
    # A vehicle of 0.5 m width on the same paths reaches it: the turn radius is not the limit.
    narrow = TraversableConfig(vehicle_width_m=0.5, safety_margin_m=0.1)
    feas_n, reach_n = scene(0.0, narrow)
    assert feas_n[gap].any() and reach_n[gap].any()


def test_open_gap_between_a_and_b_reachable() -> None:
    feas, reach = scene(0.0, TraversableConfig())
    assert feas[cell(1.2, 9.0)] and reach[cell(1.2, 9.0)]
    assert reach[cell(1.2, 14.0)]  # and the road beyond it


def test_reachable_is_subset_of_feasible_and_starts_at_vehicle() -> None:
    feas, reach = scene(0.0, TraversableConfig())
    assert not (reach & ~feas).any()
    assert reach[cell(0.0, 1.0)]


def test_tighter_steering_limit_reaches_less() -> None:
    # Open road: a 20 deg limit cannot reach cells beside the vehicle that 35 deg reaches.
    trav = (CENTRES[..., 1] >= -1.0) & (np.abs(CENTRES[..., 0]) <= 9.5)
    reach = {}
    for phi in (20.0, 35.0):
        cfg = TraversableConfig(max_steering_deg=phi)
        feas = feasible_mask(CENTRES, trav, BoundaryLine(0.0, -9.5), BoundaryLine(0.0, 9.5), [], cfg)
        reach[phi] = reachable_mask(feas, build_path_family(GRID, cfg), exempt_below_y_m=0.0)
    near_side = (np.abs(CENTRES[..., 0]) > 6.0) & (CENTRES[..., 1] < 6.0)
    assert reach[35.0][near_side].sum() > reach[20.0][near_side].sum()


def reachable_reference(feasible: np.ndarray, paths, exempt_below_y_m: float) -> np.ndarray:
    """The docstring of reachable_mask, path by path: each path's rear-axle cells up to its first
    sample whose rear or front axle is neither in a feasible cell nor in an exempt one."""
    flat = feasible.ravel()
    reach = np.zeros(flat.size, dtype=bool)
    for rear, front, ry, fy in zip(
        paths.rear_flat, paths.front_flat, paths.rear_y_m, paths.front_y_m, strict=True
    ):
        for r, f, y_r, y_f in zip(rear, front, ry, fy, strict=True):
            rear_ok = r >= 0 and (flat[r] or y_r < exempt_below_y_m)
            front_ok = f >= 0 and (flat[f] or y_f < exempt_below_y_m)
            if not (rear_ok and front_ok):
                break
            reach[r] = True
    return reach.reshape(feasible.shape) & feasible


def test_reachable_mask_is_the_path_by_path_prefix_union() -> None:
    # Random feasible sets (blobs of varying density) and exempt distances, one kept gather index
    # reused across them (it must follow the exempt distance).
    config = TraversableConfig()
    paths = build_path_family(GRID, config)
    rng = np.random.default_rng(7)
    index = PathIndex()
    for density, exempt in [(0.98, 0.0), (0.995, 1.2), (0.9, 3.0), (1.0, 0.0), (0.0, 2.0), (0.99, -1.0)]:
        feas = rng.random(GRID.shape) < density
        expected = reachable_reference(feas, paths, exempt)
        assert np.array_equal(reachable_mask(feas, paths, exempt_below_y_m=exempt), expected)
        assert np.array_equal(reachable_mask(feas, paths, exempt_below_y_m=exempt, index=index), expected)
    assert reachable_reference(np.ones(GRID.shape, bool), paths, 0.0).sum() > 100  # the test reaches far


def test_feasible_mask_on_the_grid_axes_equals_it_on_every_centre() -> None:
    # The detector passes the centres' x row and y column (a grid is separable); same cells.
    config = TraversableConfig()
    trav = np.ones(GRID.shape, dtype=bool)
    axes = (CENTRES[:1, :, 0], CENTRES[:, :1, 1])
    obstacles = [disc(-2.5, 7.0, 2.5), disc(4.5, 9.0, 2.0)]
    for left, right in [(LEFT, RIGHT), (BoundaryLine(0.13, -3.1), BoundaryLine(-0.07, 2.9)), (None, RIGHT)]:
        full = feasible_mask(CENTRES, trav, left, right, obstacles, config)
        assert np.array_equal(feasible_mask(CENTRES, trav, left, right, obstacles, config, axes=axes), full)
        assert 0 < full.sum() < full.size
