"""The envs' perception: cast the LiDAR rig, run both detectors, stack their grids as channels.

One frame per control step (the sensors' 10 Hz): the paper N rig (native or reduced) plus paper T's
bumper LUX are cast from the vehicle's true pose with sensor noise from the env's generator, and the
detectors get the INS pose, exactly as on a real vehicle. With ``ObservationConfig.scan_every`` = k
> 1 a frame is cast every k-th step only, and the steps between carry the last frame's channels
and hazard cells to the current INS pose. Channels on the observation grid:

- ``negative``: cells of paper N's detector (:class:`~negobs_gym.detector.NegativeObstacleDetector`);
- ``positive``: obstacle cells of paper T's detector
  (:class:`~negobs_gym.detector.TraversableRegionDetector`), or with
  ``ObservationConfig.positive_detector = "structure"`` the cells of paper N's rig's returns that
  stand above its ground map (:class:`~negobs_gym.detector.StructureDetector`); this frame's, or
  with ``ObservationConfig.positive_hold_s`` > 0 also those seen within that many seconds;
- ``traversable``: paper T's traversable region;
- ``observed``: cells holding at least one LiDAR return this frame (the rest is unknown); the
  safety filter's ``governed`` mode reads it through ``hazard_state()`` (:attr:`DetectorGrid.observed`).
"""

from __future__ import annotations

import functools
import multiprocessing
import os

import numpy as np

from negobs_gym.core.grid import carry_layer, carry_points
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector import (
    Detection,
    FusionConfig,
    NegativeDetectorConfig,
    NegativeObstacleDetector,
    StructureConfig,
    StructureDetector,
    TraversableConfig,
    TraversableRegion,
    TraversableRegionDetector,
)
from negobs_gym.detector.fusion import in_box
from negobs_gym.detector.memory import PointHold
from negobs_gym.sensors.lidar import PendingRigScan, frame_noise_key, start_rig_scan
from negobs_gym.sensors.noise import NoiseConfig
from negobs_gym.sensors.raycast import RayCaster, make_caster
from negobs_gym.sensors.rigs import LUX_FORWARD_M, Rig, paper_n_rig, paper_n_rig_reduced, paper_t_rig
from negobs_gym.sensors.roi import HeightEnvelope, RoiConfig, RoiSelector
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World
from negobs_gym.spec import ObservationConfig

__all__ = ["DetectorGrid", "env_rig", "world_products"]

LUX_NAME = "lux"


def env_rig(rig: str, lux_forward_m: float = LUX_FORWARD_M) -> Rig:
    """Paper N's rig plus paper T's bumper LUX (``lux_forward_m`` ahead of the rear axle): native
    resolution (``"native"``, ``"roi"``) or ``"reduced"``."""
    base = paper_n_rig_reduced() if rig == "reduced" else paper_n_rig()
    return Rig(name=f"{base.name}+lux", mounts=base.mounts + paper_t_rig(forward_m=lux_forward_m).mounts)


def cast_threads(config: ObservationConfig) -> int:
    """Ray-cast threads: the config's, else 1 in a worker process, else 2 (at most the CPU count)."""
    if config.raycast_threads is not None:
        return config.raycast_threads
    if multiprocessing.parent_process() is not None:
        return 1
    return max(1, min(2, os.cpu_count() or 1))


def pin_worker_blas(config: ObservationConfig) -> None:
    """In a worker process, the BLAS to ``config.worker_blas_threads`` threads (vector-env
    workers already fill the cores); nothing in a main process or when it is None."""
    if config.worker_blas_threads is not None and multiprocessing.parent_process() is not None:
        _limit_blas_threads(config.worker_blas_threads)


@functools.cache
def _limit_blas_threads(count: int) -> None:
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # scikit-learn brings it; without it the BLAS keeps its default
        return
    threadpool_limits(limits=count, user_api="blas")


@functools.lru_cache(maxsize=4)
def roi_selector(rig: Rig, config: RoiConfig) -> RoiSelector:
    """One selector (and its mask cache) per rig and region, shared by the envs of a process."""
    return RoiSelector(rig, config)


#: The grid channels whose cells the safety filter reads (``hazard_state()``).
HAZARD_CHANNELS = ("negative", "positive")


def world_products(
    config: ObservationConfig, world: World, vehicle: Vehicle, cache: dict | None = None
) -> tuple[RayCaster, HeightEnvelope | None]:
    """The ray caster of ``world`` and, for the ``roi`` rig or ``scan_far_from_m``, its height
    envelope: taken from ``cache`` (one dict per world) or built into it."""
    cache = {} if cache is None else cache
    pin_worker_blas(config)
    threads = cast_threads(config)
    key = ("caster", config.raycast_backend, threads, config.raycast_isa, config.raycast_fast_terrain)
    if key not in cache:
        cache[key] = make_caster(
            world,
            config.raycast_backend,
            exclude_body_ids=(vehicle.body_id,),
            threads=threads,
            isa=config.raycast_isa,
            fast_terrain=config.raycast_fast_terrain,
        )
    if config.rig != "roi" and config.far_region_xy_m is None:
        return cache[key], None
    if "heights" not in cache:
        cache["heights"] = HeightEnvelope(world, exclude_body_ids=(vehicle.body_id,))
    return cache[key], cache["heights"]


class DetectorGrid:
    """Runs the rig and both detectors each control step (or every ``config.scan_every``-th, the
    last frame carried between, with ``config.scan_far_from_m`` the grid's far part cast and
    detected between); keeps the last frame for rendering."""

    def __init__(
        self,
        config: ObservationConfig,
        world: World,
        vehicle: Vehicle,
        rng: np.random.Generator,
        cache: dict | None = None,
    ) -> None:
        """``cache`` (one dict per world, e.g. ``CachedWorld.extras``) keeps the ray caster and the
        height envelope of ``world`` for the next episode on it."""
        self.config = config
        self.rig = env_rig(config.rig, config.lux_forward_m)
        self._vehicle = vehicle
        self._rng = rng
        self._noise = NoiseConfig(enabled=config.sensor_noise)
        self._caster, heights = world_products(config, world, vehicle, cache)
        self._roi: RoiSelector | None = None
        self._roi_recent: list = []  # this episode's band sets: its casts depend on nothing else
        self._heights = heights
        if heights is not None and config.rig == "roi":
            self._roi = roi_selector(self.rig, RoiConfig(region_xy_m=config.grid.extent_xy_m))
        self._far: RoiSelector | None = None  # casts the grid's far part between frames
        self._far_recent: list = []
        self._far_scans: dict[str, StructuredScan] | None = None  # this step's far part, if any
        if config.far_region_xy_m is not None:
            self._far = roi_selector(self.rig, RoiConfig(region_xy_m=config.far_region_xy_m))
        fusion = FusionConfig(tighten_on_match=config.tighten_pairs)
        self.negative = NegativeObstacleDetector(NegativeDetectorConfig(grid=config.grid, fusion=fusion))
        by_structure = config.positive_detector == "structure"
        self.traversable = TraversableRegionDetector(
            TraversableConfig(
                obstacle_hold_s=0.0 if by_structure else config.positive_hold_s,
                kalman_ego_motion=config.lux_ego_motion,
            ),
            grid=config.grid,
        )
        self.structure = (
            StructureDetector(StructureConfig(hold_s=config.positive_hold_s), grid=config.grid)
            if by_structure
            else None
        )
        self.scans: dict[str, StructuredScan] = {}
        self.detection: Detection | None = None
        self.region: TraversableRegion | None = None
        self.stamp_s: float | None = None  # sensing time of the last frame (None before the first)
        self.positive: np.ndarray | None = None  # the last positive-obstacle layer detected
        self._hazard_holds = {name: PointHold(config.hazard_hold_s) for name in HAZARD_CHANNELS}
        self._hazards = {name: np.empty((0, 2)) for name in HAZARD_CHANNELS}
        self._steps_to_frame = 0  # control steps until the next frame is cast (0: at this one)
        self._frame: tuple[Pose, dict[str, np.ndarray], dict[str, np.ndarray]] | None = None
        self._pose: Pose | None = None  # INS pose of the last observe()
        self.observed: np.ndarray | None = None  # the last observe()'s observed layer (coverage)

    def observe(self, timestamp_s: float) -> dict[str, np.ndarray]:
        """Scan and detect at the vehicle's current pose; full-resolution bool layers by channel.

        Between two frames (``config.scan_every`` > 1) the last frame's layers and hazard cells
        are carried to the current INS pose, and ``stamp_s`` stays the frame's; with
        ``config.scan_far_from_m`` the grid's far part is cast and detected too (:meth:`_far_part`).
        """
        ins_pose: Pose = self._vehicle.pose()
        self._pose = ins_pose
        if self._steps_to_frame > 0:
            self._steps_to_frame -= 1
            if self._far is not None:
                return self._far_part(ins_pose, timestamp_s)
            # the key a frame would take: the frames that are cast get an every-step run's noise
            frame_noise_key(self._rng, self._noise)
            layers = self._carried(ins_pose)
            self.observed = layers["observed"]
            return layers
        self._steps_to_frame = self.config.scan_every - 1
        self._far_scans = None
        frame = self._cast(self._roi, self._roi_recent, timestamp_s)
        # paper T first: it reads the LUX alone, so it runs while the largest sensor is cast
        self.region = self.traversable.update(frame.scan(LUX_NAME), ins_pose)
        self.scans = frame.result()
        self.detection = self.negative.update(self.scans, ins_pose)
        self.stamp_s = float(timestamp_s)
        if self.structure is not None:
            positive = self.structure.update(self.scans, ins_pose, self.detection.ground_map)
        else:
            positive = np.asarray(self.region.positive_obstacles, dtype=bool)
        self.positive = positive
        for name, layer in zip(HAZARD_CHANNELS, (self.detection.grid, positive), strict=True):
            self._hazards[name] = self._held_cells(name, layer, ins_pose, float(timestamp_s))
        layers = {
            "negative": self.detection.grid,
            "positive": positive,
            "traversable": np.asarray(self.region.traversable, dtype=bool),
            "observed": self._observed(self.scans),
        }
        if self.config.scan_every > 1:
            self._frame = (ins_pose, layers, dict(self._hazards))
        self.observed = layers["observed"]
        return layers

    def _far_part(self, ins_pose: Pose, timestamp_s: float) -> dict[str, np.ndarray]:
        """A step between frames with ``config.scan_far_from_m``: the grid's part beyond it cast
        (and the whole LUX), paper N's detector run on it as a partial frame and paper T on the
        LUX; the rest of the last frame carried to ``ins_pose``. ``stamp_s`` stays the last whole
        frame's: the near part of the grid is that old."""
        # one noise key per step, as a whole frame: the far rays equal an every-step run's
        frame = self._cast(self._far, self._far_recent, timestamp_s)
        if self.structure is None:  # the structure channel needs the whole frame: carried
            self.region = self.traversable.update(frame.scan(LUX_NAME), ins_pose)
        scans = frame.result()
        self._far_scans = scans
        layers = self._carried(ins_pose)
        self.detection = self.negative.update(scans, ins_pose, self.config.far_region_xy_m)
        layers["negative"] = self.detection.grid
        self._hazards["negative"] = self._held_cells("negative", self.detection.grid, ins_pose, timestamp_s)
        if self.structure is None:
            layers["positive"] = np.asarray(self.region.positive_obstacles, dtype=bool)
            layers["traversable"] = np.asarray(self.region.traversable, dtype=bool)
            self.positive = layers["positive"]
            self._hazards["positive"] = self._held_cells(
                "positive", layers["positive"], ins_pose, timestamp_s
            )
        layers["observed"] = layers["observed"] | self._observed(scans)
        self.observed = layers["observed"]
        return layers

    def _cast(self, selector: RoiSelector | None, recent: list, timestamp_s: float) -> PendingRigScan:
        """The rig's frame from the true pose, started (the largest sensor casting on the caster's
        pool threads): the rays ``selector`` picks for the current height bands (``recent``: this
        episode's band sets), their range images cropped to the cast columns; every ray without
        a selector."""
        true_pose = self._vehicle.true_pose()
        subsets = None
        if selector is not None:
            subsets = selector.subsets_for_bands(self._heights.bands(true_pose, selector.tiles), recent)
        return start_rig_scan(
            self.rig,
            self._caster,
            true_pose,
            noise=self._noise,
            rng=self._rng,
            timestamp_s=timestamp_s,
            subsets=subsets,
            crop=subsets is not None,
        )

    def align_frames(self, env_steps: int) -> None:
        """Cast the next frames at the steps where the env's step count, ``env_steps`` now, is a
        multiple of ``config.scan_every`` (``scan_clock = "env"``; call after the reset's frame)."""
        self._steps_to_frame = (-(env_steps + 1)) % self.config.scan_every

    @property
    def pose(self) -> Pose | None:
        """INS pose of the last ``observe()`` (None before the first)."""
        return self._pose

    @property
    def far_scans(self) -> dict[str, StructuredScan] | None:
        """This step's scans of the grid's far part (``config.scan_far_from_m``), cropped to their
        cast columns; None on a whole frame's step or a carried one."""
        return self._far_scans

    @property
    def far_region_xy_m(self) -> tuple[float, float, float, float] | None:
        """The vehicle-frame box the far-part steps cast and detect (None without them)."""
        return self.config.far_region_xy_m

    @property
    def frame_pose(self) -> Pose | None:
        """INS pose of the last cast frame (with ``scan_every`` 1: of the last ``observe()``)."""
        return self._frame[0] if self._frame is not None else self._pose

    def _carried(self, pose: Pose) -> dict[str, np.ndarray]:
        """The last frame's layers and hazard cells moved from its INS pose to ``pose``."""
        frame_pose, layers, hazards = self._frame
        index = self.config.grid.carry_index(frame_pose, pose)
        for name in HAZARD_CHANNELS:
            self._hazards[name] = carry_points(hazards[name], frame_pose, pose)
        return {name: carry_layer(layer, index) for name, layer in layers.items()}

    def to_current(self, points: np.ndarray) -> np.ndarray:
        """Vehicle-frame points (N, 2 or 3) of the last frame in the vehicle frame of the last
        ``observe()`` (the same points when that was a frame)."""
        if self._frame is None or self._frame[0] == self._pose:
            return points
        frame_pose = self._frame[0]
        pts = np.asarray(points, dtype=np.float64)
        if pts.shape[-1] == 2:
            return carry_points(pts, frame_pose, self._pose)
        return self._pose.to_vehicle(frame_pose.to_world(pts))

    def points_vehicle(self) -> np.ndarray:
        """(N, 3) returns of the last frame, all sensors, in the vehicle frame of the last
        ``observe()`` (for rendering); on a step that cast the far part, its returns replace the
        frame's there."""
        pts = self.to_current(_returns(self.scans))
        if self._far_scans is None:
            return pts
        box = self.config.far_region_xy_m
        return np.concatenate([pts[~in_box(pts, box)], _returns(self._far_scans)])

    def detected_outlines(self) -> list[np.ndarray]:
        """Outlines (vertices, 2) of the last detection's obstacles in the vehicle frame of the
        last ``observe()``."""
        if self.detection is None:
            return []
        outlines = [o.outline_xy_m for o in self.detection.obstacles]
        return outlines if self._far_scans is not None else [self.to_current(o) for o in outlines]

    def negative_cells_xy_m(self) -> np.ndarray:
        """(N, 2) vehicle-frame centres of the last frame's negative-obstacle cells, plus those of
        the last ``config.hazard_hold_s`` seconds (at the last frame's INS pose)."""
        return self._hazards["negative"]

    def positive_cells_xy_m(self) -> np.ndarray:
        """The same for the positive-obstacle cells (the channel ``config.positive_detector``
        fills: paper T's obstacles or the structure channel)."""
        return self._hazards["positive"]

    def _held_cells(self, name: str, layer: np.ndarray, pose: Pose, stamp_s: float) -> np.ndarray:
        """The cells of ``layer`` with those held from earlier frames, (N, 2) vehicle frame."""
        cells = self.config.grid.centres_of(layer)
        if self.config.hazard_hold_s <= 0:
            return cells
        points = np.column_stack([cells, np.zeros(len(cells))])
        held = self._hazard_holds[name].recall_and_keep(points, pose, stamp_s)
        return np.concatenate([cells, held[:, :2]])

    def _observed(self, scans: dict[str, StructuredScan]) -> np.ndarray:
        """Cells holding a return, from each scan's points as they are (no gathered copy)."""
        mask = np.zeros(self.config.grid.shape, dtype=bool)
        for s in scans.values():
            mask |= self.config.grid.occupied(s.points_vehicle[..., :2])
        return mask


def _returns(scans: dict[str, StructuredScan]) -> np.ndarray:
    """(N, 3) vehicle-frame returns of all ``scans`` (the rays with a range)."""
    pts = [s.points_vehicle[np.isfinite(s.ranges_m)] for s in scans.values()]
    return np.concatenate(pts) if pts else np.empty((0, 3))
