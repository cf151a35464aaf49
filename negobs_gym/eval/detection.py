"""Detection-recall evaluation of negative-obstacle detections (paper N §4.2, Table 7; docs/eval.md).

Everything happens on the vehicle-centred 20 cm grid (:class:`negobs_gym.core.GridSpec`):
ground-truth outlines (world frame) are mapped to the vehicle frame and rasterised; a detected
obstacle (a vehicle-frame outline or a connected blob of grid cells) recalls a ground-truth obstacle
when they share at least ``min_overlap_cells`` cells. A detected obstacle that overlaps no ground
truth and no track-border cell is a false alarm. Recall is binned by the ground-truth size in grid
cells and by its distance (paper N Table 7 layout). Pure numpy/scipy; no simulator import.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from negobs_gym.core.geometry import distance_to_polyline, points_in_polygon
from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, GeometryError, require


@dataclass(frozen=True, kw_only=True)
class DetectionEvalConfig:
    """Matching rule and Table 7 bins."""

    # paper N Table 7 rows: 15-19, 20-24, ..., 40-44, 45-55 cells; half-open [lo, hi) edges
    size_bin_edges_cells: tuple[int, ...] = (15, 20, 25, 30, 35, 40, 45, 56)
    # paper N Table 7 columns: 2 m bins from 6 m to 20 m
    distance_bin_edges_m: tuple[float, ...] = (6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0)
    min_overlap_cells: int = 1  # "overlaps": at least one shared 20 cm cell
    border_band_m: float = 0.6  # half-width of the track-border face band (not in paper N)
    # distance a ground truth is binned by: "centre" = its marked cells' centre to the vehicle
    # origin (paper N §4.2: the marked region's centre to the INS centre); "nearest" = its nearest
    # cell centre (what a brake needs)
    bin_distance: str = "centre"
    # a detected outline that overlaps a ground truth only beyond the grid's edge (a pit just
    # behind the grid's rear edge, its detection reaching one row into the grid) is not a false
    # alarm: the overlap is also looked for on the grid widened by this much on every side.
    # 0 = only cells inside the grid count (the rule before; it counted such detections false)
    edge_margin_m: float = 1.0

    def __post_init__(self) -> None:
        for name in ("size_bin_edges_cells", "distance_bin_edges_m"):
            edges = np.asarray(getattr(self, name), dtype=np.float64)
            require(edges.ndim == 1 and edges.size >= 2, name, "needs at least two edges")
            require(bool(np.all(np.isfinite(edges))), name, "edges must be finite")
            require(bool(np.all(np.diff(edges) > 0)), name, "edges must be strictly increasing")
        require(
            self.min_overlap_cells >= 1, "min_overlap_cells", f"must be >= 1, got {self.min_overlap_cells}"
        )
        require(
            math.isfinite(self.border_band_m) and self.border_band_m >= 0,
            "border_band_m",
            f"must be finite and >= 0, got {self.border_band_m}",
        )
        require(
            math.isfinite(self.edge_margin_m) and self.edge_margin_m >= 0,
            "edge_margin_m",
            f"must be finite and >= 0, got {self.edge_margin_m}",
        )
        require(
            self.bin_distance in ("centre", "nearest"),
            "bin_distance",
            f"must be 'centre' or 'nearest', got {self.bin_distance!r}",
        )


def _as_polygon(outline: np.ndarray, name: str) -> np.ndarray:
    poly = np.asarray(outline, dtype=np.float64)
    if poly.ndim != 2 or poly.shape[1] < 2 or poly.shape[0] < 1:
        raise GeometryError(f"{name}: expected an (N, 2) outline, got shape {poly.shape}")
    poly = poly[:, :2]
    if not np.all(np.isfinite(poly)):
        raise GeometryError(f"{name}: outline contains NaN or inf")
    return poly


def world_outline_to_vehicle(
    outline_xy_m: np.ndarray, pose: Pose, ground_z_m: float | np.ndarray | None = None
) -> np.ndarray:
    """Map a world-frame ground outline (N, 2) to vehicle-frame (x, y).

    Args:
        outline_xy_m: world-frame polygon (N, 2), e.g. ``NegativeObstacle.outline_xy_m``.
        pose: vehicle pose at the frame (true pose for ground truth).
        ground_z_m: world Z of the outline (scalar or (N,)), e.g. the rim height ``floor_z_m +
            depth_m``; None uses the pose height. It only matters when the vehicle is pitched or
            rolled (1 cm per 0.3 m of height at 2 deg).
    """
    poly = _as_polygon(outline_xy_m, "outline_xy_m")
    z = np.broadcast_to(
        np.asarray(pose.z if ground_z_m is None else ground_z_m, dtype=np.float64), (len(poly),)
    )
    if not np.all(np.isfinite(z)):
        raise GeometryError("ground_z_m: contains NaN or inf")
    return pose.to_vehicle(np.column_stack([poly, z]))[:, :2]


def rasterize_outline(outline_xy_m: np.ndarray, grid: GridSpec) -> np.ndarray:
    """Boolean (rows, cols) mask of grid cells covered by a vehicle-frame polygon.

    A cell is covered when its centre lies inside the polygon (even-odd rule). An outline that
    covers no cell centre (a 1- or 2-point hull, a sliver) marks the cells holding its vertices
    instead, so a detection is never silently empty.
    """
    poly = _as_polygon(outline_xy_m, "outline_xy_m")
    mask = np.zeros(grid.shape, dtype=bool)
    if len(poly) >= 3:
        rows, cols = grid.window(poly.min(axis=0), poly.max(axis=0))
        if rows.start < rows.stop and cols.start < cols.stop:
            mask[rows, cols] |= points_in_polygon(grid.cell_centres()[rows, cols], poly)
    if not mask.any():
        row, col, ok = grid.cell_of(poly)
        mask[row[ok], col[ok]] = True
    return mask


def components_from_grid(obstacle_grid: np.ndarray) -> list[np.ndarray]:
    """Split a boolean obstacle grid into one cell mask per 8-connected blob."""
    grid = np.asarray(obstacle_grid)
    if grid.ndim != 2:
        raise GeometryError(f"obstacle_grid: expected a 2-D grid, got shape {grid.shape}")
    labels, count = ndimage.label(grid.astype(bool), structure=np.ones((3, 3), dtype=bool))
    return [labels == k for k in range(1, count + 1)]


def track_border_mask(
    centreline_vehicle_xy_m: np.ndarray, width_m: float, grid: GridSpec, band_m: float
) -> np.ndarray:
    """Cells within ``band_m`` of either track border (a border is ``width_m / 2`` from the centre line).

    Detections on the border faces (verge, embankment drop-off) are real drops, not false alarms.
    """
    line = _as_polygon(centreline_vehicle_xy_m, "centreline_vehicle_xy_m")
    require(line.shape[0] >= 2, "centreline_vehicle_xy_m", "needs at least two points")
    require(math.isfinite(width_m) and width_m > 0, "width_m", f"must be > 0, got {width_m}")
    dist = distance_to_polyline(grid.cell_centres(), line, 0.5 * width_m + band_m)
    return np.abs(dist - 0.5 * width_m) <= band_m


@dataclass(frozen=True)
class FrameMatch:
    """Matching result of one frame.

    Attributes:
        truth_cells: grid-cell count of each ground-truth obstacle (0 = outside the grid).
        truth_distance_m: distance from the vehicle origin to each ground truth's nearest cell
            centre (NaN when outside the grid).
        truth_centre_distance_m: distance from the vehicle origin to the centre (mean cell
            centre) of each ground truth's cells, paper N §4.2's distance (NaN when outside).
        truth_recalled: whether each ground truth overlaps a detected obstacle.
        false_alarms: detected obstacles overlapping neither ground truth nor a track border.
        detections: number of detected obstacles with at least one cell in the grid.
        false_alarm_index: indices into the ``detected`` argument of the false alarms (so a caller
            can label each one, e.g. with the terrain under it).
    """

    truth_cells: np.ndarray
    truth_distance_m: np.ndarray
    truth_centre_distance_m: np.ndarray
    truth_recalled: np.ndarray
    false_alarms: int
    detections: int
    false_alarm_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


def match_frame(
    detected: Sequence[np.ndarray],
    truth_outlines_vehicle: Sequence[np.ndarray],
    grid: GridSpec,
    config: DetectionEvalConfig | None = None,
    border_mask: np.ndarray | None = None,
) -> FrameMatch:
    """Match one frame's detected obstacles to ground truth on the grid.

    Args:
        detected: per detected obstacle, either a vehicle-frame outline (N, 2) or a boolean cell
            mask of shape ``grid.shape`` (e.g. from :func:`components_from_grid`). A detection
            with no cell inside the grid is not judged (neither a hit nor a false alarm).
        truth_outlines_vehicle: ground-truth rim outlines in the vehicle frame (see
            :func:`world_outline_to_vehicle`).
        grid: the evaluation grid.
        config: matching rule; defaults to :class:`DetectionEvalConfig()`.
        border_mask: optional (rows, cols) mask of track-border cells that are not false alarms.
    """
    cfg = config if config is not None else DetectionEvalConfig()
    if border_mask is not None:
        border_mask = np.asarray(border_mask, dtype=bool)
        if border_mask.shape != grid.shape:
            raise GeometryError(f"border_mask: shape {border_mask.shape} != grid shape {grid.shape}")
    det_masks, det_outlines = [], []
    for i, item in enumerate(detected):
        arr = np.asarray(item)
        if arr.dtype == bool:
            if arr.shape != grid.shape:
                raise GeometryError(f"detected[{i}]: mask shape {arr.shape} != grid shape {grid.shape}")
            det_masks.append(arr)
            det_outlines.append(None)
        else:
            det_masks.append(rasterize_outline(arr, grid))
            det_outlines.append(arr)
    truth_masks = [rasterize_outline(o, grid) for o in truth_outlines_vehicle]
    in_grid = np.array([k for k, m in enumerate(det_masks) if m.any()], dtype=np.int64)
    det_masks = [det_masks[k] for k in in_grid]  # wholly outside the grid: not judged
    n_t, n_d = len(truth_masks), len(det_masks)
    n_cells = grid.rows * grid.cols
    flat_t = np.array([m.ravel() for m in truth_masks], dtype=np.int32).reshape(n_t, n_cells)
    flat_d = np.array([m.ravel() for m in det_masks], dtype=np.int32).reshape(n_d, n_cells)
    overlap = flat_t @ flat_d.T
    hits = overlap >= cfg.min_overlap_cells
    truth_cells = flat_t.sum(axis=1).astype(np.int64)
    centres = grid.cell_centres().reshape(-1, 2)
    dist_all = np.linalg.norm(centres, axis=1)
    truth_dist = np.array(
        [dist_all[m.ravel()].min() if m.any() else np.nan for m in truth_masks], dtype=np.float64
    )
    centre_dist = np.array(
        [np.hypot(*centres[m.ravel()].mean(axis=0)) if m.any() else np.nan for m in truth_masks],
        dtype=np.float64,
    )
    explained = hits.any(axis=0) if n_t else np.zeros(n_d, dtype=bool)
    if border_mask is not None and n_d:
        explained |= (flat_d @ border_mask.ravel().astype(np.int32)) >= cfg.min_overlap_cells
    if cfg.edge_margin_m > 0 and n_t and not explained.all():
        explained |= _overlap_past_edge(
            [det_outlines[k] for k in in_grid], truth_outlines_vehicle, ~explained, grid, cfg
        )
    return FrameMatch(
        truth_cells=truth_cells,
        truth_distance_m=truth_dist,
        truth_centre_distance_m=centre_dist,
        truth_recalled=hits.any(axis=1) if n_d else np.zeros(n_t, dtype=bool),
        false_alarms=int(np.count_nonzero(~explained)),
        detections=n_d,
        false_alarm_index=in_grid[~explained],
    )


def _overlap_past_edge(
    outlines: Sequence[np.ndarray | None],
    truths: Sequence[np.ndarray],
    which: np.ndarray,
    grid: GridSpec,
    config: DetectionEvalConfig,
) -> np.ndarray:
    """(n,) True where a detected outline (``which`` of them) overlaps a ground truth on the grid
    widened by ``config.edge_margin_m`` (masks, None here, cannot be widened)."""
    m = config.edge_margin_m
    wide = GridSpec(
        cell_m=grid.cell_m, ahead_m=grid.ahead_m + m, back_m=grid.back_m + m, side_m=grid.side_m + m
    )
    truth_masks = [rasterize_outline(t, wide) for t in truths]
    out = np.zeros(len(outlines), dtype=bool)
    for k in np.flatnonzero(which):
        if outlines[k] is None:
            continue
        mask = rasterize_outline(outlines[k], wide)
        out[k] = any(int(np.count_nonzero(mask & t)) >= config.min_overlap_cells for t in truth_masks)
    return out


def distance_bins(match: FrameMatch, config: DetectionEvalConfig) -> np.ndarray:
    """Each ground truth's distance bin (index into ``config.distance_bin_edges_m``; -1 or the bin
    count outside them), by ``config.bin_distance``."""
    distance = match.truth_centre_distance_m if config.bin_distance == "centre" else match.truth_distance_m
    return np.digitize(np.nan_to_num(distance, nan=-1.0), config.distance_bin_edges_m) - 1


@dataclass
class RecallTable:
    """Accumulates :class:`FrameMatch` results into paper N Table 7 counts (size x distance)."""

    config: DetectionEvalConfig = field(default_factory=DetectionEvalConfig)
    frames: int = 0
    false_alarms: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.config, DetectionEvalConfig):
            raise ConfigError("config", "must be a DetectionEvalConfig")
        shape = (len(self.config.size_bin_edges_cells) - 1, len(self.config.distance_bin_edges_m) - 1)
        self.seen = np.zeros(shape, dtype=np.int64)
        self.recalled = np.zeros(shape, dtype=np.int64)

    def add(self, match: FrameMatch) -> None:
        """Count one frame (distance bin by ``config.bin_distance``); ground truth outside every bin
        is ignored."""
        self.frames += 1
        self.false_alarms += match.false_alarms
        s = np.digitize(match.truth_cells, self.config.size_bin_edges_cells) - 1
        d = distance_bins(match, self.config)
        ok = (s >= 0) & (s < self.seen.shape[0]) & (d >= 0) & (d < self.seen.shape[1])
        np.add.at(self.seen, (s[ok], d[ok]), 1)
        np.add.at(self.recalled, (s[ok], d[ok]), match.truth_recalled[ok].astype(np.int64))

    def recall(self) -> np.ndarray:
        """Recall per (size bin, distance bin); NaN where no ground truth was seen."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.seen > 0, self.recalled / np.maximum(self.seen, 1), np.nan)

    def false_alarms_per_frame(self) -> float:
        """False alarms divided by frames (NaN before the first frame)."""
        return self.false_alarms / self.frames if self.frames else math.nan
