"""Detector cost: a LiDAR frame cast and detected, paper N's and paper T's detectors, clustering,
and the Embree ray caster against PyBullet's.

The frames come from a drive along a winding course at ~7 m/s (10 Hz): per frame the native rig
(HDL-64E S2 + two HDL-32E + LUX, 360°, sensor noise on) is cast with Embree, paper N's detector
runs on it and paper T's on the LUX scan; the same pose is cast again with the envs' default
ROI rig (only the rays the observation grid needs) for paper N's detector. The dense case is a
field of 100 pits, >= 2,000 candidate pairs a frame, for fusion matching and DBSCAN.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from negobs_gym.bench.harness import Figure, Figures, Suite, median_ms, positive_counts
from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.detector import (
    NegativeDetectorConfig,
    NegativeObstacleDetector,
    TraversableRegionDetector,
    cluster_obstacles,
)
from negobs_gym.detector.synthetic import Hole, hdl32_side_scan, hdl64_scan
from negobs_gym.envs.perception import LUX_NAME, env_rig
from negobs_gym.sensors import paper_n_rig, paper_t_rig
from negobs_gym.sensors.lidar import scan_rays_world, scan_rig
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.raycast.agreement import agreement_terrain, compare_ranges
from negobs_gym.sensors.raycast.embree_backend import EmbreeCaster, EmbreeConfig
from negobs_gym.sensors.raycast.pybullet_backend import PyBulletCaster
from negobs_gym.sensors.roi import HeightEnvelope, RoiConfig, RoiSelector
from negobs_gym.sim import presets
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

GRID = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)  # the envs' observation grid
CAST_THREADS = 2  # Embree threads, as an env's main process casts
MAX_RANGE_M = 120.0  # HDL-64E S2 datasheet range (the LUX's 200 m cut to it)
DENSE_PITS_Y_M = np.linspace(6.0, 19.5, 10)  # 10 rows of pits ahead ...
DENSE_PITS_X_M = (-11.25, -8.75, -6.25, -3.75, -1.25, 1.25, 3.75, 6.25, 8.75, 11.25)  # ... 10 across


@dataclass(frozen=True)
class DetectorSize:
    """How much the detector suite measures."""

    frames: int  # frames of the drive
    dense_frames: int  # frames of the dense pit field
    cluster_rounds: int  # timed clustering calls per frame (the fastest counts)
    cast_repeats: int  # casts per caster in the ray-cast comparison (the fastest counts)

    def __post_init__(self) -> None:
        positive_counts(self)


def _cluster_ms(pairs: list[tuple[np.ndarray, np.ndarray]], rounds: int) -> float:
    """Median over frames of the fastest of ``rounds`` DBSCAN + outline calls on their confirmed pairs."""
    config = NegativeDetectorConfig().clustering
    best = np.full(len(pairs), np.inf)
    for _ in range(rounds):
        for k, (a, b) in enumerate(pairs):
            t = time.perf_counter()
            cluster_obstacles(a, b, config)
            best[k] = min(best[k], time.perf_counter() - t)
    return 1e3 * float(np.median(best))


def _confirmed(detection) -> tuple[np.ndarray, np.ndarray]:
    fused = detection.pairs
    return fused.a_m[fused.confirmed], fused.b_m[fused.confirmed]


def drive_frames(size: DetectorSize) -> Figures:
    """Per-frame medians along the winding course: cast, paper N, paper T, the ROI frame, clustering."""
    rig = env_rig("native")
    rng = np.random.default_rng(0)
    parts: dict[str, list[float]] = {k: [] for k in ("cast", "paper_n", "paper_t", "roi_cast", "roi_paper_n")}
    pairs = []
    with World(presets.winding_course(seed=0, length_m=120.0)) as world:
        vehicle = Vehicle(world)
        caster = make_caster(world, "auto", exclude_body_ids=(vehicle.body_id,), threads=CAST_THREADS)
        roi = RoiSelector(rig, RoiConfig(region_xy_m=(-GRID.side_m, GRID.side_m, -GRID.back_m, GRID.ahead_m)))
        heights = HeightEnvelope(world, exclude_body_ids=(vehicle.body_id,))
        recent: list = []  # the drive's band sets (RoiSelector.subsets_for_bands)
        paper_n = NegativeObstacleDetector(NegativeDetectorConfig(grid=GRID))
        roi_paper_n = NegativeObstacleDetector(NegativeDetectorConfig(grid=GRID))
        paper_t = TraversableRegionDetector(grid=GRID)
        world.step(60)
        vehicle.set_speed(7.0)
        for k in range(size.frames + 1):  # frame 0 warms caches and compiled kernels, untimed
            vehicle.apply(0.3, 0.0, 0.0)
            world.step(24)
            pose = vehicle.true_pose()
            t0 = time.perf_counter()
            scans = scan_rig(rig, caster, pose, rng=rng, timestamp_s=world.sim_time_s)
            t1 = time.perf_counter()
            detection = paper_n.update(scans, pose)
            t2 = time.perf_counter()
            paper_t.update(scans[LUX_NAME], pose)
            t3 = time.perf_counter()
            subsets = roi.subsets_for_bands(heights.bands(pose, roi.tiles), recent)
            roi_scans = scan_rig(rig, caster, pose, rng=rng, subsets=subsets, timestamp_s=world.sim_time_s)
            t4 = time.perf_counter()
            roi_paper_n.update(roi_scans, pose)
            t5 = time.perf_counter()
            if k > 0:
                for name, dt in zip(parts, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True):
                    parts[name].append(dt)
                pairs.append(_confirmed(detection))
    native = np.add(np.add(parts["cast"], parts["paper_n"]), parts["paper_t"])
    roi_frame = np.add(parts["roi_cast"], parts["roi_paper_n"])
    return {
        "native_frame_ms": Figure(median_ms(native), "ms", "native full-rig frame: cast + paper N + paper T"),
        "roi_frame_ms": Figure(
            median_ms(roi_frame), "ms", "ROI-rig frame (the envs' default): cast + paper N"
        ),
        "native_cast_ms": Figure(
            median_ms(parts["cast"]), "ms", "Embree cast of the native rig + LUX, 2 threads"
        ),
        "paper_n_update_ms": Figure(median_ms(parts["paper_n"]), "ms", "paper N update on the native rig"),
        "paper_t_update_ms": Figure(median_ms(parts["paper_t"]), "ms", "paper T update on a LUX frame"),
        "cluster_ms": Figure(
            _cluster_ms(pairs, size.cluster_rounds), "ms", "DBSCAN + outlines of a frame's confirmed pairs"
        ),
    }


def dense_field(size: DetectorSize) -> Figures:
    """Paper N's update and clustering on analytic scans of 100 pits (2 cm range noise)."""
    holes = [
        Hole(x0_m=h.x0_m + dx, x1_m=h.x1_m + dx, y0_m=h.y0_m, y1_m=h.y1_m, depth_m=h.depth_m)
        for h in (Hole.ahead(float(y), width_m=1.0, length_m=1.0, depth_m=0.8) for y in DENSE_PITS_Y_M)
        for dx in DENSE_PITS_X_M
    ]
    rng = np.random.default_rng(0)
    detector = NegativeObstacleDetector()
    seconds, pairs = [], []
    for k in range(size.dense_frames):
        scans = {
            "hdl64": hdl64_scan(holes, noise_sigma_m=0.02, rng=rng),
            "hdl32_left": hdl32_side_scan(holes, side="left", noise_sigma_m=0.02, rng=rng),
            "hdl32_right": hdl32_side_scan(holes, side="right", noise_sigma_m=0.02, rng=rng),
        }
        for scan in scans.values():
            _ = scan.points_vehicle  # the cloud is the input, as a rig's scan arrives: untimed
        pose = Pose(x=0.0, y=0.05 * k, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)  # creeping 5 cm a frame
        t = time.perf_counter()
        detection = detector.update(scans, pose)
        seconds.append(time.perf_counter() - t)
        pairs.append(_confirmed(detection))
    return {
        "dense_update_ms": Figure(
            median_ms(seconds), "ms", "paper N update on a 100-pit field (>= 2,000 pairs)"
        ),
        "dense_cluster_ms": Figure(
            _cluster_ms(pairs, size.cluster_rounds), "ms", "clustering on the 100-pit field"
        ),
    }


def _best_s(cast, origins: np.ndarray, directions: np.ndarray, repeats: int) -> tuple[float, np.ndarray]:
    best, ranges = np.inf, None
    for _ in range(repeats):
        t = time.perf_counter()
        ranges = cast(origins, directions, MAX_RANGE_M)
        best = min(best, time.perf_counter() - t)
    return best, ranges


def raycast(size: DetectorSize) -> Figures:
    """One revolution of the native rig + LUX on the ray-cast agreement scene (pit, trench, rock,
    pedestrian, car, mound, a second vehicle): Embree (the default packets) against PyBullet."""
    terrain = agreement_terrain(seed=0)
    with World(terrain) as world:
        own = Vehicle(world)
        xy, yaw = terrain.track.pose_at(9.0, 2.2)
        Vehicle(world, start_pose=Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw)))
        embree = EmbreeCaster.from_world(
            world, exclude_body_ids=[own.body_id], config=EmbreeConfig(auto_update=False)
        )
        bullet = PyBulletCaster(world.client_id, exclude_body_ids=[own.body_id], num_threads=0)
        sxy, syaw = terrain.track.pose_at(4.0)
        own.reset(Pose(float(sxy[0]), float(sxy[1]), 0.0, 0.0, 0.0, float(syaw)))
        rays = [scan_rays_world(m, own.true_pose()) for m in (*paper_n_rig().mounts, *paper_t_rig().mounts)]
        origins, directions = np.concatenate([r[0] for r in rays]), np.concatenate([r[1] for r in rays])
        embree_s, fast = _best_s(embree.cast, origins, directions, size.cast_repeats)
        bullet_s, reference = _best_s(bullet.cast, origins, directions, size.cast_repeats)
    agreement = compare_ranges(reference, fast, tol_m=0.01)
    return {
        "raycast_ms": Figure(
            1e3 * embree_s, "ms", f"Embree cast of {len(origins):,} rays (native rig + LUX), one thread"
        ),
        "speedup_vs_pybullet": Figure(
            bullet_s / embree_s, "x", "Embree's speed over PyBullet's rayTestBatch"
        ),
        "raycast_agreement": Figure(
            agreement.overall, "", "share of rays with PyBullet's hit/miss and range within 1 cm"
        ),
    }


SUITE = Suite(
    name="detector",
    what="detector cost",
    full=DetectorSize(frames=40, dense_frames=10, cluster_rounds=5, cast_repeats=3),
    quick=DetectorSize(frames=8, dense_frames=3, cluster_rounds=2, cast_repeats=1),
    measurements=(drive_frames, dense_field, raycast),
)
