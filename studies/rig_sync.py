"""Benchmark: paper N's detector on a three-LiDAR rig whose side clouds are brought to the lead's
time (``negobs detect --cloud``; negobs_gym.detector.io.sync.scan_at_time).

The synthetic rig (top HDL-64, side HDL-32s rolled 90 deg) approaches a 1 x 1 m pit at 25 km/h
while turning 6 deg/s; the side clouds are 40 ms older than the top's. Per update it times
``NegativeObstacleDetector.update`` on the three scans as recorded (as a rig with
phase-locked sensors has them) and with the side clouds brought to the lead's time every update
(the vehicle's motion as each side scan's ``column_motion``: its points moved in one compiled pass,
its mounting and per-ray tables as recorded). The two cases alternate,
``--rounds`` times ``--updates`` updates each. Last line: ``moved_overhead_ms=<median difference>``.

Run: python studies/rig_sync.py [--updates N] [--rounds N]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from scipy.spatial.transform import Rotation

from negobs_gym.detector import NegativeObstacleDetector
from negobs_gym.detector.io import PoseTrack
from negobs_gym.detector.io.sync import scan_at_time
from negobs_gym.detector.synthetic import Hole, hdl32_side_scan, hdl64_scan

SPEED_MPS, TURN_RAD_S, SIDE_LAG_S, PERIOD_S = 25 / 3.6, np.radians(6.0), 0.04, 0.1


def update_times_ms(moved: bool, updates: int) -> list[float]:
    """Milliseconds per detector update (scans brought to the lead's time included) of one approach."""
    times = np.arange(-0.2, updates * PERIOD_S + 0.2, 0.02)
    track = PoseTrack(
        times,
        np.column_stack([SPEED_MPS * times, np.zeros_like(times), np.zeros_like(times)]),
        Rotation.from_euler("z", TURN_RAD_S * times[:, None]).as_quat(),
    )
    hole = Hole.ahead(12.0, 1.0, 1.0, 0.8)
    scans = {
        "hdl64": hdl64_scan([hole]),
        "hdl32_left": hdl32_side_scan([hole], side="left"),
        "hdl32_right": hdl32_side_scan([hole], side="right"),
    }
    detector = NegativeObstacleDetector()
    out = []
    for k in range(updates):
        lead_s = k * PERIOD_S
        start = time.perf_counter()
        frame = {}
        for name, scan in scans.items():
            side = name != "hdl64"
            scan = dataclasses.replace(scan, timestamp_s=lead_s - SIDE_LAG_S if side else lead_s)
            frame[name] = scan_at_time(scan, track, lead_s) if moved and side else scan
        detector.update(frame, track.at(lead_s))
        out.append((time.perf_counter() - start) * 1e3)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=30, help="updates per approach")
    parser.add_argument("--rounds", type=int, default=3, help="alternating runs of each case")
    args = parser.parse_args()
    fixed, moved = [], []
    for _ in range(args.rounds):
        fixed += update_times_ms(False, args.updates)[3:]  # the first updates fill the caches
        moved += update_times_ms(True, args.updates)[3:]
    f, m = float(np.median(fixed)), float(np.median(moved))
    print(f"side clouds as recorded: median {f:.1f} ms per update ({len(fixed)} updates)")
    print(f"side clouds moved to the lead's time: median {m:.1f} ms per update ({len(moved)} updates)")
    print(f"moved_overhead_ms={m - f:.1f}")


if __name__ == "__main__":
    main()
