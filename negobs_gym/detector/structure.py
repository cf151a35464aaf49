"""Positive obstacles from paper N's rig: returns standing above the local ground.

Paper N detects only negative obstacles, but its ROI step already tells ground from *structure*
(:mod:`negobs_gym.detector.roi`): a return more than ``RoiConfig.ground_tolerance_m`` above the
ground level of its polar cell, walked outward from the vehicle. The roof-mounted HDL-64 looks
down on a rock or a box and returns from its top as well as its face, so the cells of those
returns cover the obstacle's footprint as far as the ground map reaches (paper N's 20 m + margin),
where paper T's LUX on the bumper, 0.65 m up, sees a face a few cells deep between ~6 and 12 m
(docs/detector_structure.md). Returns higher than ``max_height_m`` above the ground (branches,
canopies) pass over the vehicle and are not obstacles.

:class:`StructureDetector` marks the cells of those returns on the vehicle-centred grid, optionally
holding them for ``hold_s`` seconds in the world frame (:class:`~negobs_gym.detector.memory.PointHold`)
through the rig's blind zone around the vehicle. Like the rest of this subpackage it works on
recorded scans with INS poses: no simulator.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.inputs import check_frame
from negobs_gym.detector.memory import PointHold
from negobs_gym.detector.roi import GroundMap, RoiConfig, _sector_of, build_ground_map, ray_sectors
from negobs_gym.errors import require


@dataclass(frozen=True, kw_only=True)
class StructureConfig:
    """Constants of the structure channel (in neither paper; reasons per field)."""

    # ground map of paper N's ROI step (its ground_tolerance_m, 0.25 m, is the lowest structure)
    roi: RoiConfig = field(default_factory=RoiConfig)
    # radius of the ground map when the detector builds its own: paper N's 20 m detection range
    max_range_m: float = 20.0
    # returns higher above the ground pass over the vehicle: its 1.25 m body top and the HDL-64's
    # 2.2 m mast (paper N §2), plus margin
    max_height_m: float = 2.5
    # how long a return stays marked after the rig last saw it [s]; 0 = per frame. The HDL-64's
    # lowest laser reaches the ground ~5 m out, so a low rock leaves a per-frame grid before the
    # bumper reaches it
    hold_s: float = 0.0

    def __post_init__(self) -> None:
        require(isinstance(self.roi, RoiConfig), "roi", "must be a RoiConfig")
        require(
            math.isfinite(self.max_range_m) and self.max_range_m > 0,
            "max_range_m",
            f"must be finite and > 0 [m], got {self.max_range_m!r}",
        )
        require(
            math.isfinite(self.max_height_m) and self.max_height_m > self.roi.ground_tolerance_m,
            "max_height_m",
            f"must be finite and above roi.ground_tolerance_m ({self.roi.ground_tolerance_m} m), "
            f"got {self.max_height_m!r}",
        )
        require(
            isinstance(self.hold_s, (int, float)) and math.isfinite(self.hold_s) and self.hold_s >= 0,
            "hold_s",
            f"must be finite and >= 0 [s], got {self.hold_s!r}",
        )


def structure_points(
    ground: GroundMap,
    cloud: np.ndarray,
    max_height_m: float,
    sectors: np.ndarray | None = None,
    extent_xy_m: tuple[float, float, float, float] = (-math.inf, math.inf, -math.inf, math.inf),
) -> np.ndarray:
    """(n, 3) returns of a vehicle-frame ``cloud`` (any shape (..., 3), NaN rows = no return) that
    stand on structure: inside the ground map, more than its ``ground_tolerance_m`` and at most
    ``max_height_m`` above their cell's ground level. ``sectors``: the points' sectors as
    :func:`~negobs_gym.detector.roi.ray_sectors` gives them (-1 = unknown), or None;
    ``extent_xy_m``: (x_min, x_max, y_min, y_max), only points inside it are judged (a grid's)."""
    p = np.ascontiguousarray(np.asarray(cloud, dtype=np.float64).reshape(-1, 3))
    # no table: an empty one (the kernel takes each point's own sector), not n entries of -1 a frame
    known = np.zeros(0, dtype=np.int64) if sectors is None else np.asarray(sectors).reshape(-1)
    require(sectors is None or known.size == len(p), "sectors", "needs one sector per point of the cloud")
    cfg = ground.config
    keep = np.zeros(len(p), dtype=bool)
    _mark_structure(
        p,
        np.ascontiguousarray(known, dtype=np.int64),
        ground.ground_z_m,
        cfg.bin_m,
        math.radians(cfg.sector_deg),
        cfg.ground_tolerance_m,
        float(max_height_m),
        np.asarray(extent_xy_m, dtype=np.float64),
        keep,
    )
    return p[keep]


@kernel
def _mark_structure(
    p: np.ndarray,
    known: np.ndarray,
    ground_z: np.ndarray,
    bin_m: float,
    sector_rad: float,
    low: float,
    high: float,
    extent: np.ndarray,
    keep: np.ndarray,
) -> None:
    """``keep[k]`` for the finite points of ``p`` inside the map and the ``extent`` box with
    low < z - ground <= high, each in its sector from ``known`` (empty: none known) or its angle
    (the map's cell rule, as
    :func:`~negobs_gym.detector.roi.build_ground_map` bins)."""
    n_sectors, n_bins = ground_z.shape
    reach = n_bins * bin_m
    for k in range(p.shape[0]):
        x, y, z = p[k, 0], p[k, 1], p[k, 2]
        if not (extent[0] <= x < extent[1] and extent[2] <= y < extent[3]):  # NaN compares False
            continue
        d2 = x * x + y * y
        if not (d2 < reach * reach) or not np.isfinite(z):
            continue
        s = known[k] if known.size and known[k] >= 0 else _sector_of(x, y, sector_rad)
        b = min(int(np.sqrt(d2) / bin_m), n_bins - 1)
        rise = z - ground_z[s % n_sectors, b]
        keep[k] = rise > low and rise <= high


class StructureDetector:
    """Marks returns on structure (rocks, boxes, vehicles, walls) on the grid, frame by frame."""

    def __init__(self, config: StructureConfig | None = None, grid: GridSpec | None = None) -> None:
        self.config = config if config is not None else StructureConfig()
        self.grid = grid if grid is not None else GridSpec()
        self._held = PointHold(self.config.hold_s)
        self.points_m = np.zeros((0, 3))  # the last frame's structure returns (vehicle frame)

    def reset(self) -> None:
        """Forget the held points (start of a new run)."""
        self._held.reset()
        self.points_m = np.zeros((0, 3))

    def update(
        self, scans: Mapping[str, StructuredScan], pose: Pose, ground: GroundMap | None = None
    ) -> np.ndarray:
        """(rows, cols) bool grid of the cells holding structure returns of ``scans`` (all sensors,
        one frame, taken at INS ``pose``), and with ``hold_s`` > 0 those of the frames held.

        ``ground``: the frame's ground map where paper N's detector already built it
        (:attr:`~negobs_gym.detector.Detection.ground_map`); None builds one from ``scans``. Raises
        :class:`~negobs_gym.errors.ScanError` on a pose that is not a finite :class:`Pose` or a value
        that is not a :class:`StructuredScan`. An empty mapping gives this frame no points; with
        ``hold_s`` > 0 the held points still show, at ``pose`` (a sensor dropout does not blank
        them; with no scan time they are not aged either).
        """
        check_frame(scans, pose)
        cfg = self.config
        if ground is None:
            clouds = [s.points_vehicle for s in scans.values()]
            ground = build_ground_map(clouds, cfg.max_range_m, cfg.roi)
        extent = self.grid.extent_xy_m
        found = [
            structure_points(
                ground, s.points_vehicle, cfg.max_height_m, ray_sectors(s, ground.config), extent
            )
            for s in scans.values()
        ]
        self.points_m = np.concatenate(found) if found else np.zeros((0, 3))
        mask = self.grid.occupied(self.points_m[:, :2])
        if cfg.hold_s > 0 and scans:
            stamp_s = max(float(s.timestamp_s) for s in scans.values())
            mask |= self.grid.occupied(self._held.recall_and_keep(self.points_m, pose, stamp_s)[:, :2])
        elif cfg.hold_s > 0:
            mask |= self.grid.occupied(self._held.recall(pose)[:, :2])
        return mask
