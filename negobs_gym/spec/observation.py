"""What an episode's observation holds: the grid source, rig, channels and state (``[observation]``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from negobs_gym.core.grid import GridSpec
from negobs_gym.errors import require
from negobs_gym.sensors.raycast.embree_packets import ISAS
from negobs_gym.sensors.rigs import LUX_FORWARD_M

__all__ = [
    "CHANNELS",
    "POOLINGS",
    "POSITIVE_DETECTORS",
    "RIGS",
    "ROUTE_MARGIN_M",
    "SCAN_CLOCKS",
    "SOURCES",
    "ObservationConfig",
    "PhantomConfig",
]

#: Sources of the ``grid`` observation (``ObservationConfig.source``).
SOURCES: tuple[str, ...] = ("detector", "oracle", "pem")
#: Rigs of the detector observation (see ``ObservationConfig.rig``).
RIGS: tuple[str, ...] = ("roi", "native", "reduced")
#: How ``ObservationConfig.downsample`` pools each block of fine cells.
POOLINGS: tuple[str, ...] = ("max", "count")
#: Step counts that pick the frames with ``ObservationConfig.scan_every`` > 1.
SCAN_CLOCKS: tuple[str, ...] = ("episode", "env")

#: Route-point components are clipped to +- (farthest route distance + this) [m]: the vehicle may
#: stand this far off the centre line and still see its route inside the bounds.
ROUTE_MARGIN_M = 10.0

#: What can fill the ``positive`` channel of the detector grid (``ObservationConfig.positive_detector``).
POSITIVE_DETECTORS: tuple[str, ...] = ("traversable", "structure")

#: Grid channels an observation can carry, in this fixed order.
CHANNELS: tuple[str, ...] = ("negative", "positive", "traversable", "observed")


def _is_interval(value: object, low: float, high: float) -> bool:
    """``value`` is a (lo, hi) pair of finite numbers with low <= lo <= hi <= high."""
    return (
        isinstance(value, tuple)
        and len(value) == 2
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
        and low <= value[0] <= value[1] <= high
    )


@dataclass(frozen=True, kw_only=True)
class PhantomConfig:
    """False ``negative`` clusters added to an oracle grid, so that a policy trained on the ground
    truth meets what the detectors report where no pit lies (docs/training.md, "Phantoms").

    Not in either paper: the defaults copy the false clusters the detector grid shows at the start
    of OffroadNav-v1 courses 1,000,002 and 1,000,004 (docs/notebook/training_studies.md, "Open"): the
    HDL-64's pairs over a shadowed dip 0.6-3 m beyond the track's edge, 13-16 m ahead, 1.4-1.6 m
    across and 1.4-2.6 m along the line of sight (9-10 cells of the 0.8 m observation), in 6 of
    11 frames. Each phantom is a rectangle fixed in the world beside the track, drawn at
    reset; it shows only while its centre is ``range_m`` from the vehicle (beyond
    ``oracle_range_m`` too, as the detectors' do), in each frame with ``show_probability``.
    Rewards and rules never see it. Ignored by the detector source.

    Attributes:
        per_100m: Mean number of phantoms per 100 m of the track's centre line (Poisson); 0
            (default): none, the oracle grid is the ground truth.
        beyond_edge_m: (low, high) gap between the track's edge and a phantom's near side [m],
            drawn uniformly, on either side.
        across_m: (low, high) width of a phantom's rectangle across the track [m], drawn
            uniformly.
        along_m: (low, high) its length along the track [m], drawn uniformly.
        range_m: (low, high) distance of a phantom's centre from the vehicle origin while it
            can show [m].
        show_probability: Chance that a phantom within ``range_m`` shows in a frame.
    """

    per_100m: float = 0.0
    beyond_edge_m: tuple[float, float] = (0.5, 3.0)
    across_m: tuple[float, float] = (0.4, 1.8)
    along_m: tuple[float, float] = (1.2, 2.8)
    range_m: tuple[float, float] = (12.0, 16.0)
    show_probability: float = 0.55

    def __post_init__(self) -> None:
        require(
            isinstance(self.per_100m, (int, float))
            and not isinstance(self.per_100m, bool)
            and math.isfinite(self.per_100m)
            and 0 <= self.per_100m <= 100,
            "per_100m",
            f"must be a number in [0, 100], got {self.per_100m!r}",
        )
        for name, low in (("beyond_edge_m", 0.0), ("across_m", 0.2), ("along_m", 0.2), ("range_m", 0.0)):
            value = getattr(self, name)
            require(
                _is_interval(value, low, 100.0),
                name,
                f"must be (low, high) with {low:g} <= low <= high <= 100 [m], got {value!r}",
            )
        p = self.show_probability
        require(
            isinstance(p, (int, float)) and not isinstance(p, bool) and 0 <= p <= 1,
            "show_probability",
            f"must be in [0, 1], got {p!r}",
        )

    @property
    def enabled(self) -> bool:
        """Whether any phantom is drawn."""
        return self.per_100m > 0


@dataclass(frozen=True, kw_only=True)
class ObservationConfig:
    """What the ``grid`` observation holds.

    Attributes:
        source: ``"detector"`` casts the LiDAR rig and stacks the detectors' grids (see
            :mod:`negobs_gym.envs.perception`); ``"oracle"`` rasterises the ground truth (ablations);
            ``"pem"`` rasterises the ground truth and applies a perception-error model of the
            detector grid's ``negative`` channel fitted on the detector settings below
            (:mod:`negobs_gym.envs.pem`, docs/pem.md), at the oracle's cost.
        rig: ``"roi"`` (default: paper N's native-resolution rig, casting only the rays that can
            return a point inside ``grid`` plus the detectors' neighbourhoods; inside the grid the
            scans equal the native ones, see :mod:`negobs_gym.sensors.roi`), ``"native"`` (the
            full 360 deg native rig) or ``"reduced"`` (half resolution, blind beyond ~12 m; kept
            for comparison). All carry paper T's bumper LUX. Recall and rates: docs/performance.md.
        raycast_backend: ``"auto"`` (Embree when ``embreex`` is installed, else PyBullet),
            ``"embree"`` or ``"pybullet"``.
        raycast_threads: Threads per Embree cast; None = 2 (at most the CPU count) in a main
            process and 1 in a worker process of a vector env, whose processes already share the
            cores (docs/performance.md).
        worker_blas_threads: BLAS threads (numpy's and scipy's, through ``threadpoolctl``) in a
            worker process of a vector env, set when its detector grid is built: 1 (default), as
            the processes already share the cores; None leaves the BLAS's own count (on 2 cores
            the rates were equal within 3 %: docs/notebook/performance.md, "Detector-grid envs
            on 2 processes").
        raycast_isa: Embree's kernels: ``"native"`` (the CPU's widest, fastest) or one instruction
            set (``"avx2"``: the same scans on every AVX2 or AVX-512 CPU; docs/determinism.md).
        raycast_fast_terrain: Embree's fast triangle test on the terrain, every ray it may have
            let through cast again robustly (``EmbreeConfig.fast_terrain``: ranges within float32
            rounding of the robust scene's, the cast ~0.75x as long on an Intel AVX-512 CPU);
            False: the robust scene.
        sensor_noise: Range noise and dropout on the simulated scans.
        scan_every: Cast the rig and run the detectors every this many control steps (1, the
            default: every step, the sensors' 10 Hz as in both papers). Between two frames the
            last frame's channels and the safety filter's hazard cells are carried to the current
            INS pose (ego-motion, as paper N's fusion registers frames), so a step costs physics
            only (unless ``scan_far_from_m``); the hazards then age up to ``scan_every - 1``
            control periods (``NegObsEnv.max_perception_age_s``), from which the safety filter's
            ``perception_timeout_s`` counts. Ignored by the oracle source.
        scan_clock: With ``scan_every`` > 1, which step count picks the frames after the reset's
            (always a frame): ``"episode"`` (default: the episode's steps k, 2k, ...; the same
            seed gives the same episode whatever the env ran before) or ``"env"`` (the steps at
            which the env's count of steps since it was made is a multiple of k: the envs of a
            lockstep vector env, which all step together, then cast on the same steps, so a
            lockstep step waits for one frame at most every k steps instead of at nearly every
            step once their episodes have ended at different steps; an episode then depends on
            how many steps the env ran before it; a vector env may set that count,
            ``NegObsEnv.sync_scan_clock``, as ``PrefetchVecEnv`` does).
            Rates, recall and braking: docs/performance.md, "Scanning every k-th step".
        scan_far_from_m: With ``scan_every`` > 1, the steps between frames cast the grid's part
            beyond this forward distance [m] (with the whole LUX) and run paper N's detector on
            it as a partial frame (its fusion updates only the pairs there) and paper T on the
            LUX; the near part is carried. Paper N's fusion confirms a pit after three hits, so
            far pits, which the rig sees for few frames before they come near, need every frame;
            near ones are seen for many. None (default): nothing cast between frames. 12.0 kept
            the every-step rig's fused recall in every 2 m bin from 6 to 20 m at k = 2 to 6; 8.0
            at k = 3 kept that and the braking campaign's stops before a 0.4 m trench, which is
            confirmed only within ~12 m, for ~0.64x the CPU per step (docs/notebook/performance.md,
            "Casting the far part between frames").
        channels: Subset of :data:`CHANNELS`, in that order.
        grid: Extent and cell size of the vehicle-centred grid (paper N §3.4: 20 cm cells).
        downsample: Integer block size for pooling the grid (1 = full resolution).
        pooling: How each ``downsample`` x ``downsample`` block becomes one cell: ``"max"`` (1 when
            any of its fine cells is set, so a one-cell obstacle survives) or ``"count"`` (how
            many are set, 0 to ``downsample**2``: where in the block an obstacle lies, which the
            maximum hides, at the same input size).
        max_speed_mps: Speed that maps to the top of the ``state`` range [m/s].
        max_goal_distance_m: Goal vector components are clipped to +- this [m].
        route_points_m: Distances ahead along the track's centre line [m] whose points, in the
            vehicle frame (x right, y forward), are appended to ``state`` after the goal vector:
            the route a vehicle's navigation system hands its local planner (neither paper trains
            a policy; OffroadNav-v1 uses 5, 10 and 15 m, a 1.5 s to 4 s preview at its speeds).
            Empty (default) keeps the 5-value state. Components are clipped to
            +- (the farthest distance + ``ROUTE_MARGIN_M``).
        oracle_range_m: With ``source="oracle"``, obstacle cells (``negative``, ``positive``)
            farther than this from the vehicle origin stay empty: an oracle that sees as far as
            the detectors find pits reliably (OffroadNav-v1: 14 m, where paper N's fused recall is
            still ~0.96 here, docs/detector_features.md), so a policy trained on it does not count
            on seeing pits 25 m ahead. None: the whole grid. Ignored by the detector source.
        positive_detector: With ``source="detector"``, what fills the ``positive`` channel:
            ``"traversable"`` (default: paper T's obstacle clusters from the bumper LUX, a rock's
            near face between ~6 and 12 m) or ``"structure"`` (paper N's rig's returns standing
            above its ROI ground map, tops and faces to ~22 m;
            :mod:`negobs_gym.detector.structure`, docs/detector_structure.md).
        positive_hold_s: With ``source="detector"``, how long obstacle points stay in the
            ``positive`` channel after the rig last saw them [s] (``TraversableConfig.obstacle_hold_s``
            or ``StructureConfig.hold_s``: a rock within ~6 m passes under the LUX's layers and
            the HDL-64's, and would vanish from the grid). 0 (default): per frame, as the papers.
            Ignored by the oracle source.
        hazard_hold_s: How long the obstacle cells the safety filter reads
            (``hazard_state()``, both channels) stay after the detector last reported them, held
            in the world frame of the INS pose [s]. Not in paper N, whose filter reads each frame
            alone: a pit the car stands or creeps beside leaves the rig's view (the HDL-64's
            blind disc, ~5 m), its cells vanish and the filter would let the car on. 0 (default):
            the last frame's cells. The observation is unchanged.
        tighten_pairs: Paper N's fusion moves a history pair's A to where the A of a frame pair
            hitting it projects on its line (``FusionConfig.tighten_on_match``; the detector grid
            and the safety filter's hazards): a pit confirmed 15-20 m out then starts at the
            close frames' last ground return instead of a far ring gap (~1 m) before its rim.
            True (default): same recall and false obstacles as paper N's history, and the
            filter no longer stops cars ~1 m early (docs/detector_features.md, "Near edge").
            False: paper N's history, each pair keeps the geometry it was first seen with.
        lux_forward_m: Where paper T's LUX sits ahead of the rear axle (the vehicle origin) [m]:
            on the front bumper (paper T §2), 5 cm beyond the body's front (3.65 m). The
            shipped policies fitted on paper T's ``positive`` channel were trained with 2.0,
            inside the body, the envs' mount until this field came; their records set it
            (docs/training.md).
        lux_ego_motion: Paper T's boundary-point estimates are carried along the last boundary
            lines as the INS pose changes between frames (``TraversableConfig.kalman_ego_motion``,
            not in paper T), so a boundary point the LUX's lower layers lose in a bend turns with
            the road, not with the car. True (default): more of the track is traversable and more
            rocks and boxes are found inside the lines (docs/notebook/training_studies.md,
            "The detector grid").
            False: paper T's F = I, the estimates held still in the vehicle frame; the shipped
            policies fitted on paper T's channels were trained so, and their records set it.
        phantoms: With ``source="oracle"``, false ``negative`` clusters beside the track
            (:class:`PhantomConfig`; none by default). Ignored by the detector source.
        pem_model: With ``source="pem"``, the PEM's JSON file (``negobs pem fit`` writes one); None
            (default): the one shipped with the package for ``positive_detector`` (docs/pem.md). A
            file fitted on other detector, rig or observation settings than these is refused.
    """

    source: str = "detector"
    rig: str = "roi"
    raycast_backend: str = "auto"
    raycast_threads: int | None = None
    worker_blas_threads: int | None = 1
    raycast_isa: str = "native"
    raycast_fast_terrain: bool = True
    sensor_noise: bool = True
    scan_every: int = 1
    scan_clock: str = "episode"
    scan_far_from_m: float | None = None
    channels: tuple[str, ...] = CHANNELS
    grid: GridSpec = field(default_factory=lambda: GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4))
    downsample: int = 4
    pooling: str = "max"
    max_speed_mps: float = 15.0
    max_goal_distance_m: float = 300.0
    route_points_m: tuple[float, ...] = ()
    oracle_range_m: float | None = None
    positive_detector: str = "traversable"
    positive_hold_s: float = 0.0
    hazard_hold_s: float = 0.0
    tighten_pairs: bool = True
    lux_forward_m: float = LUX_FORWARD_M
    lux_ego_motion: bool = True
    phantoms: PhantomConfig = field(default_factory=PhantomConfig)
    pem_model: str | None = None

    def __post_init__(self) -> None:
        require(
            self.source in SOURCES,
            "source",
            f"must be one of {SOURCES}, got {self.source!r}",
        )
        require(
            self.pem_model is None or (isinstance(self.pem_model, str) and self.pem_model != ""),
            "pem_model",
            f"must be None or a file path, got {self.pem_model!r}",
        )
        require(self.rig in RIGS, "rig", f"must be one of {RIGS}, got {self.rig!r}")
        require(
            self.raycast_backend in ("auto", "embree", "pybullet"),
            "raycast_backend",
            f"must be 'auto', 'embree' or 'pybullet', got {self.raycast_backend!r}",
        )
        require(self.raycast_isa in ISAS, "raycast_isa", f"must be one of {ISAS}, got {self.raycast_isa!r}")
        require(isinstance(self.raycast_fast_terrain, bool), "raycast_fast_terrain", "must be a bool")
        require(
            self.raycast_threads is None
            or (isinstance(self.raycast_threads, int) and 1 <= self.raycast_threads <= 64),
            "raycast_threads",
            f"must be None or an int in [1, 64], got {self.raycast_threads!r}",
        )
        require(
            self.worker_blas_threads is None
            or (type(self.worker_blas_threads) is int and 1 <= self.worker_blas_threads <= 64),
            "worker_blas_threads",
            f"must be None or an int in [1, 64], got {self.worker_blas_threads!r}",
        )
        require(
            type(self.scan_every) is int and self.scan_every >= 1,
            "scan_every",
            f"must be an int >= 1 (control steps per LiDAR frame), got {self.scan_every!r}",
        )
        require(
            self.scan_clock in SCAN_CLOCKS,
            "scan_clock",
            f"must be one of {SCAN_CLOCKS}, got {self.scan_clock!r}",
        )
        if self.scan_far_from_m is not None:
            far = self.scan_far_from_m
            require(
                isinstance(far, int | float) and not isinstance(far, bool) and math.isfinite(far),
                "scan_far_from_m",
                f"must be None or a finite distance [m], got {far!r}",
            )
            require(
                self.grid.extent_xy_m[2] < far < self.grid.extent_xy_m[3],
                "scan_far_from_m",
                f"must lie inside the grid's forward extent {self.grid.extent_xy_m[2:]}, got {far!r}",
            )
        require(len(self.channels) > 0, "channels", "must name at least one channel")
        require(
            all(c in CHANNELS for c in self.channels) and len(set(self.channels)) == len(self.channels),
            "channels",
            f"must be distinct names from {CHANNELS}, got {self.channels}",
        )
        require(
            tuple(c for c in CHANNELS if c in self.channels) == tuple(self.channels),
            "channels",
            f"must follow the order {CHANNELS}",
        )
        require(
            isinstance(self.downsample, int) and self.downsample >= 1, "downsample", "must be an int >= 1"
        )
        rows, cols = self.grid.shape
        require(
            rows % self.downsample == 0 and cols % self.downsample == 0,
            "downsample",
            f"must divide the grid shape {rows}x{cols}",
        )
        require(self.pooling in POOLINGS, "pooling", f"must be one of {POOLINGS}, got {self.pooling!r}")
        require(
            self.grid_max <= 255,
            "downsample",
            f"a count of {self.downsample}x{self.downsample} cells does not fit the uint8 grid",
        )
        for name in ("max_speed_mps", "max_goal_distance_m"):
            v = getattr(self, name)
            require(math.isfinite(v) and v > 0, name, f"must be > 0, got {v}")
        require(
            self.oracle_range_m is None or (math.isfinite(self.oracle_range_m) and self.oracle_range_m > 0),
            "oracle_range_m",
            f"must be None or finite and > 0, got {self.oracle_range_m!r}",
        )
        require(
            self.positive_detector in POSITIVE_DETECTORS,
            "positive_detector",
            f"must be one of {POSITIVE_DETECTORS}, got {self.positive_detector!r}",
        )
        for name in ("positive_hold_s", "hazard_hold_s"):
            value = getattr(self, name)
            require(
                isinstance(value, (int, float)) and math.isfinite(value) and value >= 0,
                name,
                f"must be finite and >= 0 [s], got {value!r}",
            )
        require(
            isinstance(self.tighten_pairs, bool),
            "tighten_pairs",
            f"must be a bool, got {self.tighten_pairs!r}",
        )
        require(
            isinstance(self.lux_ego_motion, bool),
            "lux_ego_motion",
            f"must be a bool, got {self.lux_ego_motion!r}",
        )
        require(
            isinstance(self.lux_forward_m, (int, float))
            and not isinstance(self.lux_forward_m, bool)
            and math.isfinite(self.lux_forward_m),
            "lux_forward_m",
            f"must be a finite distance [m], got {self.lux_forward_m!r}",
        )
        require(
            isinstance(self.phantoms, PhantomConfig),
            "phantoms",
            f"must be a PhantomConfig, got {type(self.phantoms).__name__}",
        )
        route = self.route_points_m
        require(
            isinstance(route, tuple)
            and all(isinstance(d, (int, float)) and math.isfinite(d) and d > 0 for d in route)
            and list(route) == sorted(set(route)),
            "route_points_m",
            f"must be a tuple of distinct increasing distances > 0 [m], got {route!r}",
        )

    @property
    def grid_max(self) -> int:
        """The largest value of an observed grid cell: 1, or ``downsample**2`` when counting."""
        return self.downsample**2 if self.pooling == "count" else 1

    @property
    def shape(self) -> tuple[int, int, int]:
        """(channels, rows, cols) of the observed grid after down-sampling."""
        rows, cols = self.grid.shape
        return (len(self.channels), rows // self.downsample, cols // self.downsample)

    @property
    def far_region_xy_m(self) -> tuple[float, float, float, float] | None:
        """The vehicle-frame box ``(x_min, x_max, y_min, y_max)`` the steps between frames cast and
        detect: the grid's extent from ``scan_far_from_m`` forward (None: no far-part steps)."""
        if self.scan_every == 1 or self.scan_far_from_m is None:
            return None
        x0, x1, _, y1 = self.grid.extent_xy_m
        return (x0, x1, float(self.scan_far_from_m), y1)
