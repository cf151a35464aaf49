"""Rasterisation of obstacle outlines onto the 20 cm vehicle-centred grid (paper N §3.3 step 4).

Paper N marks a cell as a negative-obstacle cell when it overlaps an obstacle's outline. Outlines
are convex (cluster hulls), so overlap is decided exactly with the separating-axis test: a cell and
a convex polygon are disjoint if and only if the cell lies wholly outside one polygon edge or
outside the polygon's bounding box.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.errors import ConfigError


def convex_overlap_mask(outline_xy_m: np.ndarray, grid: GridSpec) -> np.ndarray:
    """Boolean (rows, cols) mask of cells overlapping a convex polygon (k >= 3 vertices, either winding)."""
    poly = np.asarray(outline_xy_m, dtype=np.float64)
    if poly.ndim != 2 or poly.shape[0] < 3 or poly.shape[1] != 2 or not np.isfinite(poly).all():
        raise ConfigError("outline_xy_m", f"need a finite (k >= 3, 2) polygon, got shape {poly.shape}")
    x, y = poly[:, 0], poly[:, 1]
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        poly = poly[::-1]  # clockwise input: the outward normals below need counter-clockwise
    mask = np.zeros(grid.shape, dtype=bool)
    half = 0.5 * grid.cell_m
    r0, c0, _ = grid.cell_of(poly.min(axis=0))
    r1, c1, _ = grid.cell_of(poly.max(axis=0))
    r0, r1 = max(int(r0), 0), min(int(r1), grid.rows - 1)
    c0, c1 = max(int(c0), 0), min(int(c1), grid.cols - 1)
    if r0 > r1 or c0 > c1:
        return mask
    # centres of the window's cells (the values GridSpec.cell_centres gives them)
    x = -grid.side_m + (np.arange(c0, c1 + 1) + 0.5) * grid.cell_m
    y = -grid.back_m + (np.arange(r0, r1 + 1) + 0.5) * grid.cell_m
    centres = np.stack(np.meshgrid(x, y), axis=-1)
    edge = np.roll(poly, -1, axis=0) - poly
    normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1)  # outward for counter-clockwise polygons
    offset = np.einsum("kd,kd->k", normal, poly)
    reach = half * np.abs(normal).sum(axis=1)
    separated = (centres @ normal.T - reach) > offset  # (h, w, k): the cell lies beyond edge k
    mask[r0 : r1 + 1, c0 : c1 + 1] = ~separated.any(axis=-1)
    return mask


def obstacle_grid(outlines: Sequence[np.ndarray], grid: GridSpec) -> np.ndarray:
    """Boolean (rows, cols) negative-obstacle grid: every cell overlapping any outline."""
    mask = np.zeros(grid.shape, dtype=bool)
    for outline in outlines:
        mask |= convex_overlap_mask(outline, grid)
    return mask
