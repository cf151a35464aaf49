"""Benchmark: reading recorded scans and recovering rings (negobs_gym.detector.io / loaders).

Times ``read_recording`` on each committed real recording (tests/data/real), and
``assign_rings`` on a 208,000-point HDL-64E S2 cloud (analytic flat ground, the real unit's table)
stored laser by laser (ring from the point order) and shuffled (elevation-table fallback); also
the share of points the nominal uniform table mis-rings on that unit. Medians of ``--repeats``.
Last line: ``read_median_ms=<median over the recordings>``.

Run: python studies/real_scans.py [--repeats N]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from negobs_gym.detector.io import ScanSetup, read_recording
from negobs_gym.detector.loaders import assign_rings, recover_rings
from negobs_gym.detector.synthetic import synthetic_scan
from negobs_gym.sensors.models import hdl64e_s2, hdl64e_s2_nominal

REAL = Path(__file__).resolve().parents[1] / "tests" / "data" / "real"
RECORDINGS = {"hdl32e_a.pcap": 0.16, "hdl32e_b.pcap": 0.16, "vlp32c_nebula.pcd": 0.2}


def median_ms(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per case")
    args = parser.parse_args()
    reads = []
    for name, res in RECORDINGS.items():
        setup = ScanSetup(azimuth_resolution_deg=res)
        ms = median_ms(lambda p=REAL / name, s=setup: list(read_recording(p, s)), args.repeats)
        frames = list(read_recording(REAL / name, setup))
        print(f"{name}: {len(frames)} frames, {sum(f.n_points for f in frames)} points, read {ms:.1f} ms")
        reads.append(ms)
    real, nominal = hdl64e_s2().elevation_rad, hdl64e_s2_nominal().elevation_rad
    az = -np.pi + (np.arange(4000) + 0.5) * 2 * np.pi / 4000
    scan = synthetic_scan("hdl64", real, az, np.eye(3), np.array([0.0, 0.0, 2.2]), [])
    laser_order = scan.points_sensor[scan.valid]
    ring = np.broadcast_to(np.arange(scan.shape[0])[:, None], scan.shape)[scan.valid]
    shuffled = laser_order[np.random.default_rng(0).permutation(len(laser_order))]
    by_order = assign_rings(laser_order, nominal)
    seen = np.flatnonzero(scan.valid.any(axis=1))
    print(
        f"HDL-64E S2 cloud, {len(laser_order)} points, nominal table: point order "
        f"{by_order.source}, {(seen[by_order.ring] == ring).mean():.3f} right; nearest table entry "
        f"{(recover_rings(laser_order, nominal) != ring).mean():.3f} wrong"
    )
    print(
        f"assign_rings laser order {median_ms(lambda: assign_rings(laser_order, real), args.repeats):.1f} ms"
    )
    table_ms = median_ms(lambda: assign_rings(shuffled, real), args.repeats)
    print(f"assign_rings shuffled (table) {table_ms:.1f} ms")
    print(f"read_median_ms={np.median(reads):.1f}")


if __name__ == "__main__":
    main()
