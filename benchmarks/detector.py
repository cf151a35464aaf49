"""Benchmark: paper N negative-obstacle detector on the full native rig (HDL-64E S2 + two HDL-32E).

Scans are cast up front in the PyBullet world with the fast ray caster (braking track with a
1 x 1 x 0.8 m pit and rough ground, vehicle driving at 25 km/h, sensor noise on); the cast is timed
per frame, then ``NegativeObstacleDetector.update`` (feature pairs of the three sensors, fusion,
DBSCAN, grid) is timed on the recorded frames. Prints the cast and per-stage medians, cast +
detector (SPEC §9 goal: <= 100 ms) and, as the last line, ``median_ms=<value>`` of ``update``.
Goal (issue 4): <= 60 ms on 2 cores.

Run: python benchmarks/detector.py [--frames N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from negobs_gym.detector import (
    NegativeObstacleDetector,
    cluster_obstacles,
    extract_hdl32_pairs,
    extract_hdl64_pairs,
    obstacle_grid,
)
from negobs_gym.sensors.lidar import scan_rig
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.rigs import paper_n_rig
from negobs_gym.sim.presets import braking_track
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

SPEED_MPS = 25 / 3.6


def record_frames(
    n_frames: int, seed: int = 0, cast_ms: list[float] | None = None
) -> list[tuple[dict, object]]:
    """(scans, INS pose) of ``n_frames`` 10 Hz frames approaching a pit; cast times go to ``cast_ms``."""
    terrain = braking_track(
        ditch_distance_m=25.0, ditch_length_m=1.0, ditch_width_m=1.0, ditch_depth_m=0.8, seed=seed
    )
    rng = np.random.default_rng(seed)
    rig = paper_n_rig()
    frames = []
    with World(terrain) as world:
        vehicle = Vehicle(world, rng=rng)
        caster = make_caster(world, "auto", exclude_body_ids=(vehicle.body_id,))
        steps = round(0.1 / world.config.time_step_s)
        for _ in range(n_frames):
            vehicle.set_speed(SPEED_MPS)
            world.step(steps)
            t = time.perf_counter()
            scans = scan_rig(rig, caster, vehicle.true_pose(), rng=rng)
            if cast_ms is not None:
                cast_ms.append((time.perf_counter() - t) * 1e3)
            frames.append((scans, vehicle.pose()))
    return frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=25, help="frames (>= 20 for the issue's figure)")
    args = parser.parse_args()
    cast_ms: list[float] = []
    frames = record_frames(args.frames, cast_ms=cast_ms)
    rays = sum(s.ranges_m.size for s in frames[0][0].values())
    print(f"cast {len(frames)} frames of {rays} rays: median_cast_ms={np.median(cast_ms):.1f}")

    detector = NegativeObstacleDetector()
    cfg = detector.config
    total, stage = [], {"hdl64": [], "hdl32": [], "cluster+grid": []}
    n_obstacles = []
    for scans, pose in frames:
        t = time.perf_counter()
        detection = detector.update(scans, pose)
        total.append((time.perf_counter() - t) * 1e3)
        n_obstacles.append(len(detection.obstacles))
        # stage timings, outside the timed update (the detector's own calls are not instrumented)
        t = time.perf_counter()
        extract_hdl64_pairs(scans["hdl64"], cfg.hdl64)
        stage["hdl64"].append((time.perf_counter() - t) * 1e3)
        t = time.perf_counter()
        for name in cfg.hdl32_sensors:
            extract_hdl32_pairs(scans[name], cfg.hdl32)
        stage["hdl32"].append((time.perf_counter() - t) * 1e3)
        ok = detection.pairs.confirmed
        t = time.perf_counter()
        obstacle_grid(
            [
                o.outline_xy_m
                for o in cluster_obstacles(detection.pairs.a_m[ok], detection.pairs.b_m[ok], cfg.clustering)
            ],
            cfg.grid,
        )
        stage["cluster+grid"].append((time.perf_counter() - t) * 1e3)
    for name, ms in stage.items():
        print(f"stage {name}: median_ms={np.median(ms):.1f}")
    print(
        f"obstacles per frame: max {max(n_obstacles)}, last {n_obstacles[-1]}; "
        f"fused pairs {len(detection.pairs)}"
    )
    print(f"frames={len(total)} p90_ms={np.percentile(total, 90):.1f}")
    print(f"cast + detector: median_total_ms={np.median(np.asarray(cast_ms) + np.asarray(total)):.1f}")
    print(f"median_ms={np.median(total):.1f}")


if __name__ == "__main__":
    main()
