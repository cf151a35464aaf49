"""The observed clear distance: how far along the braking corridor the grid shows clear ground.

Eq. 18 of paper N asks whether the car can still stop before the hazard it sees. The assured
clear distance ahead asks the converse question: how far ahead has the car *seen* that there is
no hazard? Along the corridor the filter searches (:class:`~negobs_gym.safety.Corridor`), the
clear distance runs over cells that hold LiDAR returns (this frame's, or remembered from recent
frames by :class:`CoverageMemory`) and no hazard, and ends at the first hazard cell, the first
unobserved cell (behind a crest or a bank, between two rings, in the rig's blind disc) or where
the corridor leaves the grid (the detector's range). No simulator here: the grid's coverage comes
through the hazard protocol (:class:`~negobs_gym.safety.HazardState`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import require
from negobs_gym.safety.corridor import Corridor

#: What ends the observed clear distance.
ClearEnd = Literal["hazard", "unobserved", "range"]


@dataclass(frozen=True, kw_only=True)
class ClearDistance:
    """The observed clear distance along one corridor.

    Attributes:
        distance_m: Arc length from the rear axle that the grid shows clear [m] (inf only
            without a grid end, which a finite grid always has).
        end: What ends it: the first ``"hazard"`` cell, the first ``"unobserved"`` cell, or
            ``"range"`` where the corridor leaves the grid.
    """

    distance_m: float
    end: ClearEnd


def grid_exit_arc_m(corridor: Corridor, grid: GridSpec) -> float:
    """Arc length at which ``corridor`` first reaches a point on the grid's outline (inf: never):
    the ground beyond is outside the detector's grid, so unobserved."""
    x0, x1, y0, y1 = grid.extent_xy_m
    step = 0.5 * grid.cell_m
    xs = np.arange(x0, x1 + 1e-9, step)
    ys = np.arange(y0, y1 + 1e-9, step)
    outline = np.concatenate(
        [
            np.column_stack([xs, np.full_like(xs, y0)]),
            np.column_stack([xs, np.full_like(xs, y1)]),
            np.column_stack([np.full_like(ys, x0), ys]),
            np.column_stack([np.full_like(ys, x1), ys]),
        ]
    )
    return float(np.min(corridor.arcs_m(outline)))


def observed_clear_distance(
    corridor: Corridor,
    grid: GridSpec,
    observed: np.ndarray | None,
    hazards_xy_m: np.ndarray,
    *,
    unobserved_blocks: bool = True,
) -> ClearDistance:
    """The corridor's observed clear distance (module docstring).

    Args:
        corridor: The swept corridor of the proposed steering.
        grid: The vehicle-centred grid ``observed`` lies on.
        observed: (rows, cols) bool, cells observed (measured this frame or remembered); None
            counts every cell as observed.
        hazards_xy_m: (N, 2) vehicle-frame hazard points (detected cells).
        unobserved_blocks: False: unobserved cells inside the grid count as clear, and only a
            hazard or the grid's edge ends the distance.

    The cells under the car, up to its front bumper (``corridor.front_length_m``), carry it and
    never end the distance as unobserved (the roof LiDAR cannot see them).
    """
    best = ClearDistance(distance_m=grid_exit_arc_m(corridor, grid), end="range")
    hazard = corridor.hazard_distance_m(hazards_xy_m)
    if hazard <= best.distance_m:
        best = ClearDistance(distance_m=hazard, end="hazard")
    if unobserved_blocks and observed is not None:
        obs = np.asarray(observed, dtype=bool)
        require(obs.shape == grid.shape, "observed", f"must have shape {grid.shape}, got {obs.shape}")
        unseen = grid.centres_of(~obs)
        arcs = corridor.arcs_m(unseen)
        arcs = arcs[arcs >= corridor.front_length_m]
        first = float(np.min(arcs)) if arcs.size else math.inf
        if first < best.distance_m:
            best = ClearDistance(distance_m=first, end="unobserved")
    return best


class CoverageMemory:
    """Cells observed within the last ``hold_s`` seconds, kept with the INS pose they were seen at.

    Each frame's observed layer is kept with its pose; a query maps the current grid's cells into
    each kept frame's grid (nearest cell, on the ground plane, as
    :meth:`~negobs_gym.core.grid.GridSpec.carry_index` does) and ORs them: the rig's blind disc
    in front of the bumper was seen a few metres earlier and is remembered as observed. Each
    frame maps straight to the current pose, so nothing drifts cell by cell.
    """

    def __init__(self, hold_s: float) -> None:
        require(
            isinstance(hold_s, (int, float)) and math.isfinite(hold_s) and hold_s >= 0,
            "hold_s",
            f"must be finite and >= 0 [s], got {hold_s!r}",
        )
        self.hold_s = float(hold_s)
        self._frames: list[tuple[float, Pose, np.ndarray]] = []  # (stamp, pose, observed layer)

    def reset(self) -> None:
        """Forget every frame (a new episode)."""
        self._frames = []

    def add(self, stamp_s: float, pose: Pose, observed: np.ndarray) -> None:
        """Keep ``observed`` (rows, cols) seen at ``pose`` with data time ``stamp_s``; a layer with
        the stamp of the last one replaces it (a frame carried to a new pose, or extended)."""
        if self._frames and self._frames[-1][0] == stamp_s:
            self._frames.pop()
        self._frames = [f for f in self._frames if 0.0 <= stamp_s - f[0] <= self.hold_s]
        self._frames.append((float(stamp_s), pose, np.asarray(observed, dtype=bool).copy()))

    def observed(
        self, grid: GridSpec, pose: Pose, now_s: float, cells: np.ndarray | None = None
    ) -> np.ndarray:
        """(rows, cols) bool: the cells of the grid at ``pose`` observed in a kept frame no older
        than ``hold_s`` at ``now_s``; with ``cells`` (rows, cols) bool, only those are looked up
        (the rest are False)."""
        out = np.zeros(grid.shape, dtype=bool)
        if not self._frames:
            return out
        wanted = np.ones(grid.shape, dtype=bool) if cells is None else np.asarray(cells, dtype=bool)
        require(wanted.shape == grid.shape, "cells", f"must have shape {grid.shape}, got {wanted.shape}")
        rows, cols = np.nonzero(wanted)
        centres = grid.cell_centres()[rows, cols]
        world = pose.to_world(np.column_stack([centres, np.zeros(len(centres))]))
        seen = np.zeros(len(centres), dtype=bool)
        for stamp, seen_at, layer in reversed(self._frames):
            if not 0.0 <= now_s - stamp <= self.hold_s + 1e-9:
                continue
            if seen_at == pose:
                seen |= layer[rows, cols]
                continue
            row, col, inside = grid.cell_of(seen_at.to_vehicle(world)[:, :2])
            seen[inside] |= layer[row[inside], col[inside]]
        out[rows, cols] = seen
        return out
