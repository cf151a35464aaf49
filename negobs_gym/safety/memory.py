"""Hazard memory: detected hazards kept in the world frame until their cells are seen clear.

Paper N's filter reads each frame alone, and its detector can lose a confirmed pit: when the rim
enters the HDL-64's ring-free disc near the car, Eq. 16's miss update also applies to pairs no
laser can see any more. :class:`HazardMemory` keeps every hazard point the filter has read, in the
world frame of the INS pose it was read at (so it carries the INS noise, as the detector's own
history does), and hands it back in the current vehicle frame until its cell is observed clear
again: the cell holds a return in the current frame and no current hazard point. A remembered
hazard outside every sensor's view (the blind disc, behind the car) stays, and so does one within
``hold_m`` of the car, where the detector loses a pit whose floor still returns. No simulator here.
"""

from __future__ import annotations

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import require


class HazardMemory:
    """World-frame hazard points, released when the current frame sees their cell clear."""

    def __init__(self, hold_m: float = 0.0) -> None:
        require(
            isinstance(hold_m, (int, float)) and np.isfinite(hold_m) and hold_m >= 0,
            "hold_m",
            f"must be finite and >= 0, got {hold_m!r}",
        )
        self.hold_m = float(hold_m)  # points this close to the vehicle origin are never released [m]
        self._world = np.zeros((0, 3))  # remembered points, world frame (z = 0 in the vehicle frame)

    def reset(self) -> None:
        """Forget every hazard (a new episode)."""
        self._world = np.zeros((0, 3))

    def __len__(self) -> int:
        return len(self._world)

    def update(
        self, hazards_xy_m: np.ndarray, pose: Pose, grid: GridSpec, observed: np.ndarray | None
    ) -> np.ndarray:
        """Remember ``hazards_xy_m`` (vehicle frame at ``pose``) and return them with the
        remembered points not seen clear, (N, 2) in the vehicle frame at ``pose``.

        A remembered point is released when its cell on ``grid`` is ``observed`` (a return this
        frame) and holds none of ``hazards_xy_m``, unless it lies within ``hold_m`` of the vehicle
        origin; points outside the grid are kept as they are (nothing sees them). Without an
        ``observed`` layer nothing is released.
        """
        current = np.asarray(hazards_xy_m, dtype=float).reshape(-1, 2)
        held = pose.to_vehicle(self._world)[:, :2] if len(self._world) else np.zeros((0, 2))
        if len(held) and observed is not None:
            hazard_cells = grid.occupied(current)
            row, col, inside = grid.cell_of(held)
            r, c = np.where(inside, row, 0), np.where(inside, col, 0)
            far = np.hypot(held[:, 0], held[:, 1]) >= self.hold_m
            clear = inside & observed[r, c] & ~hazard_cells[r, c] & far
            held = held[~clear]
        merged = np.concatenate([current, held])
        if len(merged):  # one point per cell (of the unbounded grid): the memory stays small
            row, col, _ = grid.cell_of(merged)
            _, first = np.unique(np.column_stack([row, col]), axis=0, return_index=True)
            merged = merged[np.sort(first)]
        self._world = pose.to_world(np.column_stack([merged, np.zeros(len(merged))]))
        return merged
