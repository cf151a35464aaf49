"""Paper N's negative-obstacle detector end to end: pairs per sensor -> fusion -> DBSCAN -> 20 cm grid.

Usage on recorded or simulated scans::

    detector = NegativeObstacleDetector()
    for scans, pose in frames:  # scans: {"hdl64": StructuredScan, "hdl32_left": ..., ...}
        detection = detector.update(scans, pose)
        detection.grid  # (rows, cols) bool, vehicle-centred, Y forward (GridSpec)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.clustering import ClusteringConfig, DetectedObstacle, cluster_obstacles
from negobs_gym.detector.config import GroundCheckConfig, Hdl32FeatureConfig, Hdl64FeatureConfig
from negobs_gym.detector.fusion import FusedPairs, FusionConfig, PairFusion, in_box
from negobs_gym.detector.grid import obstacle_grid
from negobs_gym.detector.ground_checks import ground_check
from negobs_gym.detector.hdl32 import extract_hdl32_pairs
from negobs_gym.detector.hdl64 import extract_hdl64_pairs, sensor_height
from negobs_gym.detector.inputs import check_frame
from negobs_gym.detector.pairs import FeaturePairs
from negobs_gym.detector.roi import GroundMap, RoiConfig, build_ground_map, ray_sectors
from negobs_gym.errors import InterfaceError, ScanError, require

SensorMode = Literal["fused", "hdl64", "hdl32"]
SENSOR_MODES: tuple[str, ...] = ("fused", "hdl64", "hdl32")  # paper N Fig. 16: 64 only, 32 only, fused


@dataclass(frozen=True, kw_only=True)
class NegativeDetectorConfig:
    """Everything the paper N detector needs; every default is the paper's value.

    ``hdl64_sensors`` and ``hdl32_sensors`` name the scans (keys of the mapping passed to
    :meth:`NegativeObstacleDetector.update`) that each feature extractor reads; ``mode`` picks which
    of them take part (paper N Fig. 16). Scans under other names (e.g. a LUX in the same rig) are
    ignored.
    """

    mode: SensorMode = "fused"
    hdl64_sensors: tuple[str, ...] = ("hdl64",)
    hdl32_sensors: tuple[str, ...] = ("hdl32_left", "hdl32_right")
    # pairs whose near point A lies farther than this (ground-plane distance from the vehicle origin)
    # are dropped: paper N detects up to 20 m (§4.2, Table 7, distance = the obstacle's centre)
    max_range_m: float = 20.0
    # ... and HDL-64 pairs whose B (on the back wall) lies beyond max_range_m + this. 0 (default): B
    # within max_range_m too, because beyond ~20 m the HDL-64 rings are metres apart and a shadow
    # behind a crest passes Eq. 14: 1.5 m on every sensor gave 14 false obstacles per 100 frames on
    # the rough track (limit 1; docs/detector_features.md). Papers silent.
    far_wall_margin_m: float = 0.0
    # ... the same for the side HDL-32s' pairs (documented deviation). Their scan lines run radially
    # and sample the ground behind a rim every d^2 * 0.16 deg / h (0.5 m at 20 m), so their B beyond
    # max_range_m lies on the back wall just behind the rim, not past a crest metres away as the
    # HDL-64's can. 1.5 m = the longest of paper N's pits: the B of a pit whose near rim is just
    # inside max_range_m (measured: 18-20 m fused recall 0.18 -> 0.29, false obstacles unchanged).
    hdl32_far_wall_margin_m: float = 1.5
    roi: RoiConfig = field(default_factory=RoiConfig)  # Table 1 line 1, ExtractROIPoints (rule: roi.py)
    # the HDL-64's pairs checked against the frame's ground: shadow (crest), far-side and depth
    # tests (not in paper N: they cut the fused false alarms on rough ground ~25-fold at paper N's
    # recall, docs/detector_false_alarms.md; GroundCheckConfig.off() = Eq. 14 alone, as paper())
    hdl64_ground_checks: GroundCheckConfig = field(default_factory=GroundCheckConfig)
    hdl64: Hdl64FeatureConfig = field(default_factory=Hdl64FeatureConfig)  # §3.1
    hdl32: Hdl32FeatureConfig = field(default_factory=Hdl32FeatureConfig)  # §3.2
    fusion: FusionConfig = field(default_factory=FusionConfig)  # §3.3 steps 1-2, Eq. 15/16
    clustering: ClusteringConfig = field(default_factory=ClusteringConfig)  # §3.3 step 3
    grid: GridSpec = field(default_factory=GridSpec)  # §3.3 step 4: 20 cm cells, Y forward

    def __post_init__(self) -> None:
        require(
            math.isfinite(self.max_range_m) and self.max_range_m > 0, "max_range_m", "must be finite and > 0"
        )
        require(
            math.isfinite(self.far_wall_margin_m) and self.far_wall_margin_m >= 0,
            "far_wall_margin_m",
            "must be finite and >= 0",
        )
        require(
            math.isfinite(self.hdl32_far_wall_margin_m) and self.hdl32_far_wall_margin_m >= 0,
            "hdl32_far_wall_margin_m",
            "must be finite and >= 0",
        )
        require(self.mode in SENSOR_MODES, "mode", f"must be one of {SENSOR_MODES}, got {self.mode!r}")
        for name in ("hdl64_sensors", "hdl32_sensors"):
            names = getattr(self, name)
            require(
                isinstance(names, tuple) and all(isinstance(n, str) for n in names),
                name,
                "must be a tuple of sensor names",
            )
        require(
            not set(self.hdl64_sensors) & set(self.hdl32_sensors),
            "hdl32_sensors",
            "a sensor cannot be both an HDL-64 and an HDL-32",
        )
        for name, cls in (
            ("roi", RoiConfig),
            ("hdl64_ground_checks", GroundCheckConfig),
            ("hdl64", Hdl64FeatureConfig),
            ("hdl32", Hdl32FeatureConfig),
            ("fusion", FusionConfig),
            ("clustering", ClusteringConfig),
            ("grid", GridSpec),
        ):
            require(isinstance(getattr(self, name), cls), name, f"must be a {cls.__name__}")

    @classmethod
    def paper(cls, **changes: object) -> NegativeDetectorConfig:
        """Paper N's detector as published (plus the documented deviations that give its reach,
        docs/detector_features.md), without the false-alarm checks added since; ``changes`` as
        keyword arguments of the constructor."""
        return cls(**{"hdl64_ground_checks": GroundCheckConfig.off(), **changes})

    @property
    def active_sensors(self) -> tuple[str, ...]:
        """Scan names read in this mode."""
        return {
            "fused": self.hdl64_sensors + self.hdl32_sensors,
            "hdl64": self.hdl64_sensors,
            "hdl32": self.hdl32_sensors,
        }[self.mode]


@dataclass(frozen=True, eq=False)
class Detection:
    """One frame's result, in the vehicle frame at the pose passed to ``update``.

    Attributes:
        pairs: the fused pair history with posteriors (``pairs.confirmed`` are the ones clustered).
        obstacles: one :class:`DetectedObstacle` per DBSCAN cluster, nearest first; its
            ``pair_indices`` index ``pairs``.
        grid: (rows, cols) bool, cells overlapping an obstacle outline (``grid_spec`` layout).
        grid_spec: the grid's extent and resolution.
        frame_pairs: this frame's feature pairs per active sensor inside the ROI, before fusion.
        ground_map: the frame's ROI ground map (None when the ROI step is off).
    """

    pairs: FusedPairs
    obstacles: list[DetectedObstacle]
    grid: np.ndarray
    grid_spec: GridSpec
    frame_pairs: dict[str, FeaturePairs] = field(default_factory=dict)
    ground_map: GroundMap | None = None


def within_roi(
    pairs: FeaturePairs, max_range_m: float, ground: GroundMap | None, far_wall_margin_m: float = 0.0
) -> FeaturePairs:
    """The pairs whose A lies within ``max_range_m`` of the vehicle origin in the ground plane and B
    within ``max_range_m + far_wall_margin_m`` and, given a ground map, whose A and B are ground
    with no structure between them (:mod:`.roi`)."""
    keep = (np.hypot(pairs.a_m[:, 0], pairs.a_m[:, 1]) <= max_range_m) & (
        np.hypot(pairs.b_m[:, 0], pairs.b_m[:, 1]) <= max_range_m + far_wall_margin_m
    )
    if ground is not None and len(pairs):
        keep &= ground.keep_pairs(pairs.a_m, pairs.b_m, pairs.c_m)
    return FeaturePairs(pairs.sensor, pairs.a_m[keep], pairs.b_m[keep], pairs.c_m[keep])


def within_box(pairs: FeaturePairs, box_xy_m: tuple[float, float, float, float]) -> FeaturePairs:
    """The pairs whose A and B both lie in the vehicle-frame box ``(x_min, x_max, y_min, y_max)``."""
    keep = in_box(pairs.a_m, box_xy_m) & in_box(pairs.b_m, box_xy_m)
    return FeaturePairs(pairs.sensor, pairs.a_m[keep], pairs.b_m[keep], pairs.c_m[keep])


def check_coverage(
    coverage_xy_m: tuple[float, float, float, float] | None,
) -> tuple[float, float, float, float] | None:
    """``coverage_xy_m`` as four floats, or None; ScanError when it is not a finite, non-empty box."""
    if coverage_xy_m is None:
        return None
    try:
        x0, x1, y0, y1 = (float(v) for v in coverage_xy_m)
    except (TypeError, ValueError):
        raise ScanError(
            f"coverage_xy_m: must be (x_min, x_max, y_min, y_max), got {coverage_xy_m!r}"
        ) from None
    if not (all(math.isfinite(v) for v in (x0, x1, y0, y1)) and x0 < x1 and y0 < y1):
        raise ScanError(
            f"coverage_xy_m: must be finite with x_min < x_max and y_min < y_max, got {coverage_xy_m!r}"
        )
    return x0, x1, y0, y1


class NegativeObstacleDetector:
    """Paper N's detector (§3): call :meth:`update` once per synchronised frame of scans.

    Keeps the fused pair history between calls; :meth:`reset` forgets it (new episode or log).
    """

    def __init__(self, config: NegativeDetectorConfig | None = None) -> None:
        if config is not None and not isinstance(config, NegativeDetectorConfig):
            raise InterfaceError(f"config: must be a NegativeDetectorConfig, got {type(config).__name__}")
        self.config = config or NegativeDetectorConfig()
        self._fusion = PairFusion(self.config.fusion)

    def reset(self) -> None:
        """Forget the pair history."""
        self._fusion.reset()

    def update(
        self,
        scans: Mapping[str, StructuredScan],
        pose: Pose,
        coverage_xy_m: tuple[float, float, float, float] | None = None,
    ) -> Detection:
        """Detect negative obstacles in one frame of ``scans`` taken at INS ``pose``.

        ``coverage_xy_m`` declares a partial frame: the vehicle-frame box ``(x_min, x_max, y_min,
        y_max)`` whose returns the scans hold (e.g. only the far part of the grid was cast). The
        frame's pairs outside it are dropped (their features may miss neighbours that were not
        cast), and the history outside it is neither hit nor missed (:meth:`PairFusion.update`).
        None (default): a whole frame, as in paper N.

        Handling of bad input: NaN ranges are missing returns (the scan format); an empty mapping or
        scans with no returns give no new pairs (the history still ages). Raises if
        ``pose`` has NaN/inf, if a value is not a :class:`StructuredScan`, or if ``scans`` is
        non-empty but holds none of the configured sensor names (a misnamed rig) — as
        :class:`~negobs_gym.errors.ScanError` (a ``ValueError``); a malformed ``coverage_xy_m``
        is a ``ScanError`` too.
        """
        cfg = self.config
        check_frame(scans, pose)
        coverage = check_coverage(coverage_xy_m)
        known = cfg.hdl64_sensors + cfg.hdl32_sensors
        if scans and not set(scans) & set(known):
            raise ScanError(f"scans has sensors {sorted(scans)}, none of the configured {list(known)}")
        active = [name for name in cfg.active_sensors if name in scans]
        ground = None
        if cfg.roi.enabled:
            clouds = [scans[name].points_vehicle for name in active]
            sectors = [ray_sectors(scans[name], cfg.roi) for name in active]
            ground = build_ground_map(clouds, cfg.max_range_m, cfg.roi, sectors)
        frame_pairs = {}
        for name in active:
            if name in cfg.hdl64_sensors:
                scan = scans[name]
                pairs = extract_hdl64_pairs(scan, cfg.hdl64, ground)
                height = sensor_height(scan, cfg.hdl64.sensor_height_m) if len(pairs) else 1.0
                pairs = ground_check(pairs, ground, scan.translation_m, height, cfg.hdl64_ground_checks)
                margin = cfg.far_wall_margin_m
            else:
                pairs = extract_hdl32_pairs(scans[name], cfg.hdl32)
                margin = cfg.hdl32_far_wall_margin_m
            pairs = within_roi(pairs, cfg.max_range_m, ground, margin)
            frame_pairs[name] = pairs if coverage is None else within_box(pairs, coverage)
        fused = self._fusion.update(frame_pairs, pose, coverage)
        ok = fused.confirmed
        clusters = cluster_obstacles(fused.a_m[ok], fused.b_m[ok], cfg.clustering)
        confirmed_index = np.flatnonzero(ok)
        obstacles = [dataclasses.replace(c, pair_indices=confirmed_index[c.pair_indices]) for c in clusters]
        grid = obstacle_grid([ob.outline_xy_m for ob in obstacles], cfg.grid)
        return Detection(fused, obstacles, grid, cfg.grid, frame_pairs, ground)


DETECTOR_PRESETS: tuple[str, ...] = ("default", "paper")


def detector_preset(name: str) -> NegativeDetectorConfig:
    """``"default"``: ``NegativeDetectorConfig()``; ``"paper"``: :meth:`NegativeDetectorConfig.paper`."""
    require(name in DETECTOR_PRESETS, "detector", f"must be one of {DETECTOR_PRESETS}, got {name!r}")
    return NegativeDetectorConfig() if name == "default" else NegativeDetectorConfig.paper()


def with_settings(config: NegativeDetectorConfig, assignments: Sequence[str]) -> NegativeDetectorConfig:
    """``config`` with each ``"PATH=VALUE"`` applied (VALUE is TOML), PATH a dotted field path
    (``hdl64.pair_test.gamma1``, ``hdl64_ground_checks.crest_rise_m``); a field that does not exist
    or a bad value is a ConfigError naming it (:func:`negobs_gym.core.settings.replace_setting`)."""
    from negobs_gym.core.settings import parse_assignment, replace_setting

    for text in assignments:
        keys, value = parse_assignment(str(text), example="hdl64_ground_checks.crest_rise_m=0.05")
        config = replace_setting(config, keys, value)
    return config
