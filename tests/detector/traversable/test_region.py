"""Region polygon and the obstacle-shadow cut (paper T §3.4, Fig. 6)."""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path

from negobs_gym.core import GridSpec
from negobs_gym.detector.traversable import BoundaryLine, ObstacleCluster
from negobs_gym.detector.traversable.region import (
    region_mask,
    region_polygon,
    sector_pad_rad,
    shadow_mask,
    shadow_polygon,
)

GRID = GridSpec()
CENTRES = GRID.cell_centres()
ORIGIN = np.array([0.0, 3.7])


def test_region_mask_matches_polygon() -> None:
    left, right = BoundaryLine(0.2, -5.0), BoundaryLine(0.25, 4.0)
    poly = region_polygon(left, right, 3.7, 13.0)
    mask = region_mask(CENTRES, left, right, 3.7, 13.0)
    ref = Path(poly).contains_points(CENTRES.reshape(-1, 2)).reshape(mask.shape)
    assert mask.sum() > 500
    assert (mask != ref).sum() <= 0.02 * mask.sum()  # differences only on the polygon's edges


def test_region_needs_both_lines() -> None:
    assert region_polygon(None, BoundaryLine(0, 1), 0, 10).shape == (0, 2)
    assert not region_mask(CENTRES, BoundaryLine(0, -1), None, 0, 10).any()
    assert not region_mask(CENTRES, BoundaryLine(0, -1), BoundaryLine(0, 1), 10, 5).any()


def test_shadow_is_the_sector_behind_the_near_face() -> None:
    face = np.column_stack([np.linspace(1.0, 3.0, 20), np.full(20, 10.0), np.zeros(20)])
    cluster = ObstacleCluster(points_m=face, centre_xy_m=np.array([2.0, 10.0]), width_m=2.0)
    d = CENTRES - ORIGIN
    bearing, rng = np.arctan2(d[..., 0], d[..., 1]), np.hypot(d[..., 0], d[..., 1])
    mask = shadow_mask(bearing, rng, cluster, ORIGIN, GRID.cell_m / np.sqrt(2))
    kept_pad = sector_pad_rad(rng, GRID.cell_m / np.sqrt(2))  # as the detector keeps it per origin
    np.testing.assert_array_equal(
        shadow_mask(bearing, rng, cluster, ORIGIN, GRID.cell_m / np.sqrt(2), kept_pad), mask
    )
    poly = shadow_polygon(cluster, ORIGIN, 60.0)
    ref = Path(poly).contains_points(CENTRES.reshape(-1, 2)).reshape(mask.shape)
    assert ref.sum() > 100 and not (ref & ~mask).any()  # every cell of the polygon is cut

    def at(x: float, y: float) -> bool:
        row, col, _ = GRID.cell_of(np.array([x, y]))
        return bool(mask[row, col])

    assert at(2.0, 12.0) and at(4.0, 16.0)  # behind, and widening with distance (A5 side)
    assert not at(2.0, 8.0) and not at(-1.0, 12.0)  # in front of and beside the obstacle


def test_region_mask_on_the_grid_axes_equals_it_on_every_centre() -> None:
    # The detector passes the centres' x row and y column (a grid is separable); same cells.
    axes = (CENTRES[:1, :, 0], CENTRES[:, :1, 1])
    for left, right, near, far in [
        (BoundaryLine(0.0, -4.0), BoundaryLine(0.0, 4.0), 1.9, 20.0),
        (BoundaryLine(0.17, -3.3), BoundaryLine(-0.11, 3.7), 0.3, 24.1),
    ]:
        full = region_mask(CENTRES, left, right, near, far)
        assert full.any()
        assert np.array_equal(region_mask(CENTRES, left, right, near, far, axes=axes), full)
