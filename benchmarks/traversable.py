"""Benchmark: paper T traversable-region detector, one LUX frame (0.25 deg over 110 deg).

441 columns x 4 layers of an analytic scene (banked straight track with a parked car), noisy
ranges, vehicle pitch bouncing; the scans are made up front, only ``update`` is timed.
Prints per-scene medians and, as the last line, ``median_ms=<value>`` over all frames.
Goal: <= 2 ms (paper T: 25 ms on a 1 GHz Cortex-A8).

Run: python benchmarks/traversable.py [--frames N]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from negobs_gym.core import Pose
from negobs_gym.detector.traversable import Box, LuxRig, TrackScene, TraversableRegionDetector, synthetic_scan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="timed frames per scene")
    args = parser.parse_args()
    rig = LuxRig(resolution_deg=0.25, fov_deg=110.0)
    car = Box(x_m=0.5, y_m=12.25, size_x_m=1.8, size_y_m=4.5, height_m=1.5)
    scenes = {
        "straight": TrackScene(),
        "bend": TrackScene(bend_radius_m=30.0),
        "car": TrackScene(boxes=(car,)),
    }
    rng = np.random.default_rng(0)
    det = TraversableRegionDetector()
    all_ms: list[float] = []
    for name, scene in scenes.items():
        scans = [
            synthetic_scan(
                scene, rig, vehicle_pitch_rad=rng.normal(0, math.radians(0.3)), range_noise_m=0.02, rng=rng
            )
            for _ in range(20)
        ]
        det.reset()
        for s in scans:  # warm-up
            det.update(s, Pose())
        ms = []
        for i in range(args.frames):
            scan = scans[i % len(scans)]
            t0 = time.perf_counter()
            det.update(scan, Pose())
            ms.append((time.perf_counter() - t0) * 1e3)
        print(f"{name}: columns={scans[0].shape[1]} lasers={scans[0].shape[0]} median_ms={np.median(ms):.3f}")
        all_ms.extend(ms)
    print(f"median_ms={np.median(all_ms):.3f}")


if __name__ == "__main__":
    main()
