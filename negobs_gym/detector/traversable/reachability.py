"""Paper T §3.5: spatial feasibility (Eq. 12) and reachability under the turning limit (Eq. 13).

Eq. 12: a position p is feasible when it keeps ``d_c / 2 + epsilon`` from both boundary lines and
``(d_c + d_oj) / 2 + epsilon`` from every obstacle centre (d_c: vehicle width, d_oj: obstacle
width). Eq. 13: with wheelbase l and steering angle phi the rear axle turns on radius
``rho_r = l / tan(phi)`` and the front axle on ``rho_f = l / sin(phi)``.

Reachability samples a fixed family of forward paths from the rear axle (origin, heading +Y): arcs
of curvature |k| <= 1 / rho_r(phi_max) (a turn, or a turn and its counter-turn), then straight.
A path is followed until either its rear-axle point or its front-axle point (the rho_f circle)
leaves the feasible set; the cells its rear axle visits until then are reachable. The family is
built once per grid (it does not depend on the scan), so each frame costs one gather and one
cumulative AND.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.detector.traversable.boundaries import BoundaryLine
from negobs_gym.detector.traversable.config import TraversableConfig
from negobs_gym.detector.traversable.obstacles import ObstacleCluster


def feasible_mask(
    centres_xy_m: np.ndarray,
    traversable: np.ndarray,
    left: BoundaryLine | None,
    right: BoundaryLine | None,
    clusters: list[ObstacleCluster],
    config: TraversableConfig,
    axes: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Eq. 12 on every cell: traversable and far enough from boundaries and obstacle centres.

    ``axes``: the centres' x (1, cols) and y (rows, 1) when the caller keeps them (a grid's
    centres share x down a column and y along a row): the same arithmetic, broadcast.
    """
    half = config.vehicle_width_m / 2.0 + config.safety_margin_m
    x, y = (centres_xy_m[..., 0], centres_xy_m[..., 1]) if axes is None else axes
    ok = traversable.copy()
    for line in (left, right):
        if line is not None:  # BoundaryLine.distance's arithmetic
            ok &= np.abs(x - line.slope * y - line.offset_m) / np.hypot(1.0, line.slope) >= half
    for c in clusters:  # a handful of obstacles, each a vectorized test over all cells
        d = np.hypot(x - c.centre_xy_m[0], y - c.centre_xy_m[1])
        ok &= d >= (config.vehicle_width_m + c.width_m) / 2.0 + config.safety_margin_m
    return ok


@dataclass(frozen=True, eq=False)
class PathFamily:
    """Sampled forward paths: flat cell indices of rear- and front-axle samples, (paths, samples)."""

    rear_flat: np.ndarray  # int64, -1 outside the grid
    front_flat: np.ndarray
    rear_y_m: np.ndarray
    front_y_m: np.ndarray


def _arc(kappa: np.ndarray, length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Displacement (right, forward) after ``length`` on an arc of curvature ``kappa`` (> 0 right)."""
    small = np.abs(kappa) < 1e-9
    k = np.where(small, 1.0, kappa)
    h = kappa * length
    right = np.where(small, 0.0, (1.0 - np.cos(h)) / k)
    forward = np.where(small, length, np.sin(h) / k)
    return right, forward


def _rotate(right: np.ndarray, forward: np.ndarray, heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vehicle-frame (x, y) of a (right, forward) displacement made at ``heading`` (cw from +Y)."""
    c, s = np.cos(heading), np.sin(heading)
    return forward * s + right * c, forward * c - right * s


def build_path_family(grid: GridSpec, config: TraversableConfig) -> PathFamily:
    """Forward paths from the rear axle with |curvature| <= 1 / rho_r (Eq. 13), sampled on the grid.

    Two families, each over ``reach_curvatures`` curvatures and ``reach_switch_points`` arc
    lengths (up to a quarter turn at the tightest radius): a turn then straight on (a change of
    heading), and a turn followed by the opposite turn then straight on (a lane change, the manoeuvre
    of paper T Fig. 8).
    """
    k_max = 1.0 / config.rear_turn_radius_m
    n_k = 2 * (config.reach_curvatures // 2) + 1
    kappa = np.linspace(-k_max, k_max, n_k)
    s_max = (np.pi / 2.0) / k_max
    switch = np.linspace(0.0, s_max, config.reach_switch_points + 1)[1:]
    u = np.arange(0.0, config.reach_length_m + 1e-9, config.reach_step_m)
    k1 = np.concatenate([np.repeat(kappa, switch.size)] * 2)[:, None]
    s1 = np.concatenate([np.tile(switch, n_k)] * 2)[:, None]
    k2 = np.concatenate([np.zeros(n_k * switch.size), -np.repeat(kappa, switch.size)])[:, None]
    s2 = np.concatenate([np.zeros(n_k * switch.size), np.tile(switch, n_k)])[:, None]
    uu = u[None, :]
    # Segment 1: arc k1 for s1.
    u1 = np.minimum(uu, s1)
    x, y = _arc(k1, u1)
    h1 = k1 * s1
    # Segment 2: arc k2 for s2, starting at the end of segment 1 with heading h1.
    u2 = np.clip(uu - s1, 0.0, s2)
    r2, f2 = _arc(k2, u2)
    dx, dy = _rotate(r2, f2, h1)
    x, y = x + dx, y + dy
    # Segment 3: straight on.
    h2 = h1 + k2 * s2
    u3 = np.maximum(uu - s1 - s2, 0.0)
    x, y = x + u3 * np.sin(h2), y + u3 * np.cos(h2)
    heading = np.where(uu <= s1, k1 * u1, h1 + k2 * u2)
    fx = x + config.wheelbase_m * np.sin(heading)
    fy = y + config.wheelbase_m * np.cos(heading)

    def flat(px: np.ndarray, py: np.ndarray) -> np.ndarray:
        row, col, inside = grid.cell_of(np.stack([px, py], axis=-1))
        return np.where(inside, row * grid.cols + col, -1)

    return PathFamily(rear_flat=flat(x, y), front_flat=flat(fx, fy), rear_y_m=y, front_y_m=fy)


class PathIndex:
    """What :func:`reachable_mask` gathers, kept for one path family and exempt distance (the
    sensor's mount, fixed between frames): it depends on nothing in the scan.

    Per sample, where its rear and front axle read their feasibility in ``feasible.ravel()``
    extended by two cells: ``cells`` (always infeasible: outside the grid) and ``cells + 1``
    (always feasible: exempt). A path's samples after its first one outside the grid can never be
    reached, so the paths are cut after the latest such sample (a last column of ``cells`` ends
    every path), and paths equal up to there are kept once.
    """

    def __init__(self) -> None:
        self.paths: PathFamily | None = None
        self.key: tuple[float, int] | None = None
        self.rear = self.front = self.rear_cells = np.zeros((0, 1), dtype=np.intp)

    def get(
        self, paths: PathFamily, cells: int, exempt_below_y_m: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rear, front) gather indices (paths, samples + 1) and the rear axle's cells (paths, samples)."""
        key = (float(exempt_below_y_m), cells)
        if self.paths is not paths or self.key != key:
            outside = (paths.rear_flat < 0) | (paths.front_flat < 0)
            first_out = np.where(outside.any(axis=1), outside.argmax(axis=1), outside.shape[1])
            width = min(int(first_out.max()) + 1, outside.shape[1])
            rear, front = (
                np.where((y < exempt_below_y_m) & (flat >= 0), cells + 1, np.where(flat >= 0, flat, cells))
                for flat, y in ((paths.rear_flat, paths.rear_y_m), (paths.front_flat, paths.front_y_m))
            )
            rows = np.unique(
                np.concatenate([rear[:, :width], front[:, :width]], axis=1), axis=0, return_index=True
            )[1]
            rows.sort()
            end = np.full((rows.size, 1), cells)
            self.rear = np.ascontiguousarray(np.concatenate([rear[rows, :width], end], axis=1))
            self.front = np.ascontiguousarray(np.concatenate([front[rows, :width], end], axis=1))
            self.rear_cells = np.ascontiguousarray(paths.rear_flat[rows, :width])
            self.paths, self.key = paths, key
        return self.rear, self.front, self.rear_cells


@functools.lru_cache(maxsize=4)
def _index_of_sample(samples: int) -> np.ndarray:
    """0 .. samples - 1, as int16 where they fit (a cheaper comparison than int64's)."""
    index = np.arange(samples, dtype=np.int16 if samples < 2**15 else np.int64)
    index.flags.writeable = False
    return index


def reachable_mask(
    feasible: np.ndarray, paths: PathFamily, exempt_below_y_m: float, index: PathIndex | None = None
) -> np.ndarray:
    """Cells reached by the rear axle along path prefixes that stay feasible.

    Args:
        feasible: (rows, cols) Eq. 12 mask.
        paths: The sampled path family of the same grid.
        exempt_below_y_m: Samples nearer than this (the area the vehicle occupies, in front of the
            LiDAR's blind zone) count as feasible.
        index: Where a caller keeps the gather indices between frames (``PathIndex()``); built
            for this call when None.
    """
    cells = feasible.size
    rear, front, rear_cells = (index if index is not None else PathIndex()).get(
        paths, cells, exempt_below_y_m
    )
    flat_ok = np.empty(cells + 2, dtype=bool)
    flat_ok[:cells] = feasible.ravel()
    flat_ok[cells] = False
    flat_ok[cells + 1] = True
    ok = np.take(flat_ok, rear)  # take: about half the time of fancy indexing here
    ok &= np.take(flat_ok, front)
    # each path's prefix before its first infeasible sample (the appended last column is one, so
    # argmin finds it for a path feasible throughout; logical_and.accumulate costs several times more)
    sample = _index_of_sample(rear_cells.shape[1])
    prefix = sample < ok.argmin(axis=1).astype(sample.dtype)[:, None]
    reach = np.zeros(cells, dtype=bool)
    reach[rear_cells[prefix]] = True
    return reach.reshape(feasible.shape) & feasible
