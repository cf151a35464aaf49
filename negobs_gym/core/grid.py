"""The vehicle-centred grid shared by both detectors and the environments.

Cells are ``cell_m`` squares (paper N §3.4: 20 cm). Rows run along vehicle +Y (row 0 is the rear
edge, ``-back_m``), columns along vehicle +X (column 0 is the left edge, ``-side_m``). Arrays are
``(rows, cols)``; plot them with ``origin="lower"`` to see the vehicle driving up the image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.core.pose import Pose
from negobs_gym.errors import GeometryError, require


@dataclass(frozen=True, kw_only=True)
class GridSpec:
    """Extent and resolution of a vehicle-centred grid (vehicle frame: Y forward, X right)."""

    cell_m: float = 0.20  # paper N §3.4: 20 cm x 20 cm cells
    ahead_m: float = 30.0  # design range >= 25 m: paper N Table 7 evaluates to 20 m, plus margin
    back_m: float = 5.0
    side_m: float = 10.0  # design range: 10 m each side of the vehicle

    def __post_init__(self) -> None:
        for name in ("cell_m", "ahead_m", "side_m"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, name, f"must be > 0, got {value}")
        require(math.isfinite(self.back_m) and self.back_m >= 0, "back_m", f"must be >= 0, got {self.back_m}")

    @property
    def rows(self) -> int:
        """Number of cells along Y."""
        return round((self.ahead_m + self.back_m) / self.cell_m)

    @property
    def cols(self) -> int:
        """Number of cells along X."""
        return round(2 * self.side_m / self.cell_m)

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return self.rows, self.cols

    @property
    def extent_xy_m(self) -> tuple[float, float, float, float]:
        """Vehicle-frame box ``(x_min, x_max, y_min, y_max)`` the grid covers [m]."""
        return -self.side_m, self.side_m, -self.back_m, self.ahead_m

    def cell_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cell (row, col) of vehicle-frame points (..., 2) and a mask of those inside the grid.

        Points outside get the cell they would have on an unbounded grid (a box's corners clip
        its cell range); NaN points (no return) get (-1, -1), outside."""
        row, col, inside = self._cells(np.asarray(xy, dtype=np.float64))
        no_point = np.isnan(row) | np.isnan(col)
        return (
            np.where(no_point, -1.0, row).astype(np.int64),
            np.where(no_point, -1.0, col).astype(np.int64),
            inside,
        )

    def window(self, lo_xy: np.ndarray, hi_xy: np.ndarray) -> tuple[slice, slice]:
        """Row and column slices of the cells that hold the vehicle-frame box from ``lo_xy`` to
        ``hi_xy`` (finite (x, y) corners), clipped to the grid: empty where the box misses it.
        :meth:`cell_of`'s floors, on two points without arrays (an obstacle's window per frame)."""
        (x_lo, y_lo), (x_hi, y_hi) = (float(v) for v in lo_xy), (float(v) for v in hi_xy)
        rows = slice(
            max(math.floor((y_lo + self.back_m) / self.cell_m), 0),
            min(math.floor((y_hi + self.back_m) / self.cell_m) + 1, self.rows),
        )
        cols = slice(
            max(math.floor((x_lo + self.side_m) / self.cell_m), 0),
            min(math.floor((x_hi + self.side_m) / self.cell_m) + 1, self.cols),
        )
        return rows, cols

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """Whether each vehicle-frame point (..., 2) lies in a cell of the grid (NaN does not):
        :meth:`cell_of`'s mask alone."""
        return self._cells(np.asarray(xy, dtype=np.float64))[2]

    def occupied(self, xy: np.ndarray) -> np.ndarray:
        """(rows, cols) bool: the cells holding at least one of the vehicle-frame points (..., 2);
        NaN points (no return) hold none. One compiled pass over the points, with the cell
        arithmetic of :meth:`cell_of`."""
        pts = np.asarray(xy, dtype=np.float64)
        if pts.shape[-1:] != (2,):
            raise GeometryError(f"xy: must have shape (..., 2), got {pts.shape}")
        mask = np.zeros(self.rows * self.cols, dtype=bool)
        _mark_cells(pts.reshape(-1, 2), self.side_m, self.back_m, self.cell_m, self.rows, self.cols, mask)
        return mask.reshape(self.shape)

    def _cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Floored (row, col) as floats and the inside mask (NaN is outside)."""
        with np.errstate(invalid="ignore"):
            col = np.floor((xy[..., 0] + self.side_m) / self.cell_m)
            row = np.floor((xy[..., 1] + self.back_m) / self.cell_m)
            inside = (row >= 0) & (row < self.rows) & (col >= 0) & (col < self.cols)
        return row, col, inside

    def cell_centres(self) -> np.ndarray:
        """Vehicle-frame (x, y) of every cell centre, shape (rows, cols, 2)."""
        x = -self.side_m + (np.arange(self.cols) + 0.5) * self.cell_m
        y = -self.back_m + (np.arange(self.rows) + 0.5) * self.cell_m
        xx, yy = np.meshgrid(x, y)
        return np.stack([xx, yy], axis=-1)

    def centres_of(self, mask: np.ndarray) -> np.ndarray:
        """(N, 2) vehicle-frame centres of the set cells of ``mask`` (rows, cols), row-major:
        ``cell_centres()[mask]`` without building every cell's centre."""
        row, col = np.nonzero(mask)
        x = -self.side_m + (col + 0.5) * self.cell_m
        y = -self.back_m + (row + 0.5) * self.cell_m
        return np.stack([x, y], axis=1).astype(float)

    def world_centres(self, now: Pose) -> np.ndarray:
        """World (x, y, z) of every cell centre of the grid laid at pose ``now``, on its ground
        plane, shape (rows, cols, 3): :meth:`carry_index`'s first half, which one pose ``now``
        shares between all the grids carried into it."""
        ground = np.concatenate([self.cell_centres(), np.zeros((*self.shape, 1))], axis=-1)
        return now.to_world(ground)

    def carry_index(self, seen_at: Pose, now: Pose | np.ndarray) -> np.ndarray:
        """(rows, cols) flat index, into a grid laid at pose ``seen_at``, of the cell under each
        cell centre of the grid at pose ``now`` (-1 where it falls outside): moves a layer seen
        at ``seen_at`` into the grid at ``now`` (ego-motion, nearest cell; :func:`carry_layer`).
        ``now`` may be given as its :meth:`world_centres`, to carry many grids into one pose."""
        world = self.world_centres(now) if isinstance(now, Pose) else now
        row, col, inside = self.cell_of(seen_at.to_vehicle(world)[..., :2])
        return np.where(inside, row * self.cols + col, -1)


def carry_layer(layer: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``layer`` (rows, cols) moved by :meth:`GridSpec.carry_index`'s ``index``; cells it does
    not cover are False (unseen)."""
    flat = np.asarray(layer).ravel()
    return np.where(index >= 0, flat[np.maximum(index, 0)], False)


def carry_points(xy: np.ndarray, seen_at: Pose, now: Pose) -> np.ndarray:
    """(N, 2) vehicle-frame points seen at pose ``seen_at``, on the ground plane, in the
    vehicle frame of ``now``."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    ground = np.column_stack([pts, np.zeros(len(pts))])
    return now.to_vehicle(seen_at.to_world(ground))[:, :2]


@kernel
def _mark_cells(
    xy: np.ndarray, side_m: float, back_m: float, cell_m: float, rows: int, cols: int, mask: np.ndarray
) -> None:
    """Set ``mask[row * cols + col]`` for every point inside the grid (NaN compares outside)."""
    for k in range(xy.shape[0]):
        col = np.floor((xy[k, 0] + side_m) / cell_m)
        row = np.floor((xy[k, 1] + back_m) / cell_m)
        if row >= 0 and row < rows and col >= 0 and col < cols:
            mask[int(row) * cols + int(col)] = True
