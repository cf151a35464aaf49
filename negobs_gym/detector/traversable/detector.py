"""Paper T's traversable-region detector for the 4-layer LiDAR, frame by frame.

Pipeline (paper T §3): boundary points per layer (tears.py) -> Kalman filters (kalman.py) ->
least-squares boundary lines (boundaries.py) -> obstacle clusters (obstacles.py) -> region minus
obstacles and shadows (region.py) -> Eq. 12 feasibility and Eq. 13 reachability (reachability.py).
State lives only in the Kalman filters, as in the paper, and (with ``config.obstacle_hold_s`` > 0,
not in the paper) in the obstacle points of the last ``obstacle_hold_s`` seconds, kept in the
world frame of the INS pose. With ``config.kalman_ego_motion`` (not in the paper) the filters'
estimates follow the previous frame's boundary lines as the pose changes between frames.

Bad input: a scan that is not a :class:`StructuredScan`, has a laser count other than
``config.n_layers`` or elevations not in ascending (detector) order, or a pose that is not a finite
:class:`Pose` raises :class:`~negobs_gym.errors.ScanError` (a ``ValueError``) naming the problem.
NaN ranges are "no return" and are skipped, as are ranges beyond ``config.max_range_m`` (the LUX's
200 m reach); an empty scan yields no boundaries, no obstacles and empty grids (the filters only
predict).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from negobs_gym.core import libm
from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.memory import PointHold
from negobs_gym.detector.traversable.boundaries import (
    BoundaryLine,
    carry_along_line,
    drop_inconsistent,
    fit_boundary,
    passes_on_its_side,
)
from negobs_gym.detector.traversable.config import TraversableConfig
from negobs_gym.detector.traversable.kalman import BoundaryKalman
from negobs_gym.detector.traversable.obstacles import ObstacleCluster, detect_obstacles
from negobs_gym.detector.traversable.reachability import (
    PathFamily,
    PathIndex,
    build_path_family,
    feasible_mask,
    reachable_mask,
)
from negobs_gym.detector.traversable.region import (
    points_mask,
    region_mask,
    region_polygon,
    sector_pad_rad,
    shadow_mask,
    shadow_polygon,
)
from negobs_gym.detector.traversable.tears import boundary_points
from negobs_gym.errors import ScanError


@dataclass(frozen=True, eq=False)
class TraversableRegion:
    """Result of one frame, all in the vehicle frame [m] and on the detector's :class:`GridSpec`.

    Attributes:
        raw_left_m, raw_right_m: (boundary layers, 2) boundary points of this scan; NaN = none.
        left_points_m, right_points_m: Kalman-filtered boundary points; NaN = never seen.
        left_line, right_line: Least-squares boundary lines, ``None`` when a side has no points.
        obstacles: Obstacle clusters inside the boundaries.
        polygon_m: (4, 2) region between the boundaries (A1 on the LiDAR X axis), or (0, 2).
        shadow_polygons_m: Per obstacle, its near face plus the unseen sector behind it (cut out).
        traversable: (rows, cols) region minus obstacles and shadows.
        positive_obstacles: (rows, cols) cells holding obstacle-cluster points (this frame's, and
            with ``obstacle_hold_s`` > 0 those of the frames held).
        feasible: (rows, cols) Eq. 12 holds (vehicle width + margin fits).
        reachable: (rows, cols) feasible and reachable under the steering limit (Eq. 13).
        pose: The pose given with the scan.
    """

    raw_left_m: np.ndarray
    raw_right_m: np.ndarray
    left_points_m: np.ndarray
    right_points_m: np.ndarray
    left_line: BoundaryLine | None
    right_line: BoundaryLine | None
    obstacles: list[ObstacleCluster]
    polygon_m: np.ndarray
    shadow_polygons_m: list[np.ndarray]
    traversable: np.ndarray
    positive_obstacles: np.ndarray
    feasible: np.ndarray
    reachable: np.ndarray
    pose: Pose = field(default_factory=Pose)

    def channels(self) -> np.ndarray:
        """(2, rows, cols) float32 observation channels: traversable, positive obstacles (0/1)."""
        return np.stack([self.traversable, self.positive_obstacles]).astype(np.float32)


def _check_pose(pose: object) -> Pose:
    if not isinstance(pose, Pose):
        raise ScanError(f"pose must be a negobs_gym.core.Pose, got {type(pose).__name__}")
    values = pose.as_array()
    if not np.isfinite(values).all():
        raise ScanError(f"pose has a non-finite component: {tuple(values)}")
    return pose


class TraversableRegionDetector:
    """Paper T's detector; call :meth:`update` once per LUX frame, :meth:`reset` between runs."""

    def __init__(self, config: TraversableConfig | None = None, grid: GridSpec | None = None) -> None:
        """Create a detector.

        Args:
            config: Thresholds and vehicle constants (paper T defaults).
            grid: Output grid (default: the shared 20 cm vehicle-centred grid).
        """
        self.config = config if config is not None else TraversableConfig()
        self.grid = grid if grid is not None else GridSpec()
        n_bound = len(self.config.boundary_layers)
        self._kalman = BoundaryKalman(
            (2, n_bound, 2), self.config.kalman_measurement_var_m2, self.config.kalman_process_var_m2
        )
        self._centres = self.grid.cell_centres()
        # the centres' x (1, cols) and y (rows, 1): every row shares the x, every column the y
        self._axes = (self._centres[:1, :, 0].copy(), self._centres[:, :1, 1].copy())
        self._paths: PathFamily = build_path_family(self.grid, self.config)
        self._path_index = PathIndex()  # the paths' gather indices, kept while the mount stays put
        self._polar_origin: tuple[float, float] | None = None
        self._cell_bearing = np.zeros(self.grid.shape)
        self._cell_range = np.zeros(self.grid.shape)
        self._cell_pad = np.zeros(self.grid.shape)
        self._shadow_slack_m = self.grid.cell_m / math.sqrt(2.0)  # half a cell diagonal
        self._held = PointHold(self.config.obstacle_hold_s)  # obstacle points of recent frames
        self._last_pose: Pose | None = None  # the previous frame's, for kalman_ego_motion

    def reset(self) -> None:
        """Forget the filtered boundary points and the held obstacle points (start of a new run)."""
        self._kalman.reset()
        self._held.reset()
        self._last_pose = None

    def _validate(self, scan: object) -> StructuredScan:
        if not isinstance(scan, StructuredScan):
            raise ScanError(f"scan must be a negobs_gym.core.StructuredScan, got {type(scan).__name__}")
        lasers = scan.shape[0]
        if lasers != self.config.n_layers:
            raise ScanError(
                f"{scan.sensor}: the traversable-region detector needs a {self.config.n_layers}-layer scan "
                f"(IBEO LUX), got {lasers} lasers"
            )
        if not (np.diff(scan.elevation_rad) > 0).all():
            raise ScanError(f"{scan.sensor}: lasers must be in detector order (ascending elevation)")
        return scan

    def _polar(self, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bearing, range and shadow-sector pad (:func:`sector_pad_rad`) of every cell from the
        sensor origin O, kept while O stays put (a fixed mount)."""
        key = (float(origin[0]), float(origin[1]))
        if self._polar_origin != key:
            d = self._centres - origin
            self._cell_bearing = libm.arctan2(d[..., 0], d[..., 1])
            self._cell_range = np.hypot(d[..., 0], d[..., 1])
            self._cell_pad = sector_pad_rad(self._cell_range, self._shadow_slack_m)
            self._polar_origin = key
        return self._cell_bearing, self._cell_range, self._cell_pad

    def _carried(self, pose: Pose, sensor_xy_m: tuple[float, float]) -> np.ndarray:
        """The filters' points carried from the last frame's pose to ``pose``, each side's along
        the line the last frame fitted to them; a side whose carried line passes the sensor on the
        wrong side (``config.kalman_carry_min_clearance_m``) is dropped (NaN: it restarts)."""
        cfg = self.config
        carried = np.stack(
            [
                carry_along_line(
                    points, fit_boundary(points), self._last_pose, pose, cfg.kalman_carry_max_angle_deg
                )
                for points in self._kalman.state
            ]
        )
        if cfg.kalman_carry_min_clearance_m is not None:
            for points, side in zip(carried, (-1, 1), strict=True):
                line = fit_boundary(points)
                if line is not None and not passes_on_its_side(
                    line, side, sensor_xy_m, cfg.kalman_carry_min_clearance_m
                ):
                    points[:] = np.nan
        return carried

    def update(self, scan: StructuredScan, pose: Pose) -> TraversableRegion:
        """Detect the traversable region in one scan.

        Args:
            scan: A LUX-like scan (``config.n_layers`` lasers, ascending elevation).
            pose: Vehicle pose at scan time (validated and returned with the result). The paper's
                filters run in the vehicle frame with F = I, so it moves the estimates only with
                ``config.kalman_ego_motion``.

        Returns:
            The frame's :class:`TraversableRegion`.
        """
        scan = self._validate(scan)
        pose = _check_pose(pose)
        cfg = self.config
        pts = scan.points_vehicle
        ranges = scan.ranges_m
        beyond = ranges > cfg.max_range_m  # NaN compares False
        if beyond.any():
            ranges = np.where(beyond, np.nan, ranges)
            pts = np.where(beyond[..., None], np.nan, pts)
        raw_left, raw_right = boundary_points(pts, ranges, cfg)
        consistent = np.stack(
            [drop_inconsistent(side, cfg.layer_consistency_m) for side in (raw_left, raw_right)]
        )
        # the sensor's origin (moved with the middle column where the scan carries a column_motion)
        origin = np.asarray(scan.origins_vehicle(np.array([scan.shape[1] // 2]))[0, :2], dtype=np.float64)
        if cfg.kalman_ego_motion:
            if self._last_pose is not None:
                self._kalman.carry_points(self._carried(pose, (float(origin[0]), float(origin[1]))))
            self._last_pose = pose
        measured = self._kalman.gate_points(consistent, cfg.kalman_gate_x_m, cfg.kalman_gate_reset_frames)
        filtered = self._kalman.update(measured)
        left_pts, right_pts = filtered[0], filtered[1]
        left = fit_boundary(left_pts)
        right = fit_boundary(right_pts)
        obstacles = detect_obstacles(pts, left, right, cfg)

        near_y = float(origin[1])  # A1: boundaries meet the LiDAR's X axis
        ys = filtered[..., 1]
        far_y = float(np.nanmax(ys)) if np.isfinite(ys).any() else -math.inf
        polygon = region_polygon(left, right, near_y, far_y)
        traversable = region_mask(self._centres, left, right, near_y, far_y, axes=self._axes)
        obstacle_xy = (
            np.concatenate([c.points_m[:, :2] for c in obstacles]) if obstacles else np.zeros((0, 2))
        )
        if cfg.obstacle_hold_s > 0:
            points = np.concatenate([c.points_m for c in obstacles]) if obstacles else np.zeros((0, 3))
            earlier = self._held.recall_and_keep(points, pose, float(scan.timestamp_s))
            obstacle_xy = np.concatenate([obstacle_xy, earlier[:, :2]])
        positive = points_mask(self.grid, obstacle_xy)
        shadows: list[np.ndarray] = []
        if obstacles:
            bearing, rng, pad = self._polar(origin)
            far_range = float(np.hypot(self.grid.side_m, self.grid.ahead_m) + np.hypot(*origin))
            for c in obstacles:
                shadows.append(shadow_polygon(c, origin, far_range))
                traversable &= ~shadow_mask(bearing, rng, c, origin, self._shadow_slack_m, pad)
        traversable &= ~positive
        feasible = feasible_mask(self._centres, traversable, left, right, obstacles, cfg, axes=self._axes)
        reachable = reachable_mask(feasible, self._paths, exempt_below_y_m=near_y, index=self._path_index)
        return TraversableRegion(
            raw_left_m=raw_left,
            raw_right_m=raw_right,
            left_points_m=left_pts,
            right_points_m=right_pts,
            left_line=left,
            right_line=right,
            obstacles=obstacles,
            polygon_m=polygon,
            shadow_polygons_m=shadows,
            traversable=traversable,
            positive_obstacles=positive,
            feasible=feasible,
            reachable=reachable,
            pose=pose,
        )
