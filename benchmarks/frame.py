"""One native full-rig frame: cast (HDL-64 + 2x HDL-32 + LUX, 360 deg) + paper N + paper T.

Drives the vehicle along a winding course at ~7 m/s (10 Hz frames) and times, per frame, the
Embree cast of paper N's native rig plus paper T's LUX (sensor noise on), paper N's detector
(pairs, fusion, DBSCAN, grid) and paper T's detector on the LUX scan. Also times the same frame
with ROI casting (the envs' default rig), and the structure channel on the ROI frame
(``ObservationConfig.positive_detector = "structure"``: returns above paper N's ground map, which it
takes from paper N's detection). Prints per-part medians and the native frame's process
CPU time (steadier than wall time on a loaded machine); the last line is
``median_ms=<v>`` of the full native frame (cast + paper N + paper T).

Run: ``python benchmarks/frame.py [--frames 40] [--threads 2]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.detector import (
    NegativeDetectorConfig,
    NegativeObstacleDetector,
    StructureDetector,
    TraversableRegionDetector,
)
from negobs_gym.envs.perception import LUX_NAME, env_rig
from negobs_gym.sensors.lidar import scan_rig
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.roi import HeightEnvelope, RoiConfig, RoiSelector
from negobs_gym.sim import presets
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

GRID = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)  # the envs' observation grid


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--threads", type=int, default=2, help="Embree cast threads")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.frames < 1 or args.threads < 1:
        parser.error("--frames and --threads must be >= 1")
    rig = env_rig("native")
    rng = np.random.default_rng(args.seed)
    times: dict[str, list[float]] = {
        k: [] for k in ("cast", "paper_n", "paper_t", "roi_cast", "roi_paper_n", "roi_structure")
    }
    cpu: list[float] = []  # process CPU time of the native frame (all threads)
    with World(presets.winding_course(seed=args.seed, length_m=120.0)) as world:
        vehicle = Vehicle(world)
        caster = make_caster(world, "auto", exclude_body_ids=(vehicle.body_id,), threads=args.threads)
        region = (-GRID.side_m, GRID.side_m, -GRID.back_m, GRID.ahead_m)
        roi = RoiSelector(rig, RoiConfig(region_xy_m=region))
        heights = HeightEnvelope(world, exclude_body_ids=(vehicle.body_id,))
        recent: list = []  # the drive's band sets (RoiSelector.subsets_for_bands)
        det_n = NegativeObstacleDetector(NegativeDetectorConfig(grid=GRID))
        det_n_roi = NegativeObstacleDetector(NegativeDetectorConfig(grid=GRID))
        det_t = TraversableRegionDetector(grid=GRID)
        det_s = StructureDetector(grid=GRID)
        world.step(60)
        vehicle.set_speed(7.0)
        for k in range(args.frames + 1):
            vehicle.apply(0.3, 0.0, 0.0)
            world.step(24)
            pose = vehicle.true_pose()
            c0 = time.process_time()
            t0 = time.perf_counter()
            scans = scan_rig(rig, caster, pose, rng=rng, timestamp_s=world.sim_time_s)
            t1 = time.perf_counter()
            det_n.update(scans, pose)
            t2 = time.perf_counter()
            det_t.update(scans[LUX_NAME], pose)
            t3 = time.perf_counter()
            cpu.append(1e3 * (time.process_time() - c0))
            subsets = roi.subsets_for_bands(heights.bands(pose, roi.tiles), recent)
            roi_scans = scan_rig(rig, caster, pose, rng=rng, subsets=subsets, timestamp_s=world.sim_time_s)
            t4 = time.perf_counter()
            detection = det_n_roi.update(roi_scans, pose)
            t5 = time.perf_counter()
            det_s.update(roi_scans, pose, detection.ground_map)
            t6 = time.perf_counter()
            if k == 0:
                cpu.clear()
                continue  # first frame: caches and imports
            for name, dt in zip(times, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4, t6 - t5), strict=True):
                times[name].append(1e3 * dt)
    med = {k: float(np.median(v)) for k, v in times.items()}
    print(
        f"frames={args.frames} threads={args.threads} " + " ".join(f"{k}_ms={v:.1f}" for k, v in med.items())
    )
    print(f"roi_frame_median_ms={float(np.median(np.add(times['roi_cast'], times['roi_paper_n']))):.1f}")
    print(f"native_frame_cpu_median_ms={float(np.median(cpu)):.1f} (process CPU, all threads)")
    total = np.add(np.add(times["cast"], times["paper_n"]), times["paper_t"])
    print(f"median_ms={float(np.median(total)):.1f}")


if __name__ == "__main__":
    main()
