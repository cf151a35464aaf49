"""Benchmark: paper T on a recorded 4-layer LiDAR frame, its range image cropped to the field of view
or over the whole revolution (``ScanSetup.crop_columns``, what ``negobs detect --sensor lux`` reads).

A recorded LUX cloud is binned into 0.25 deg columns; over a revolution that is 1,440 columns, of
which its 110 deg field of view fills 441. The frames are paper T's analytic LUX scans of a track
between banks with a box (``detector.traversable.synthetic``, range noise 2 cm), written as
sensor-frame float32 clouds with a layer field as a driver publishes them and read back through
``fields_to_scan`` both ways. Each way runs ``TraversableRegionDetector.update`` on the same frames,
alternating, ``--rounds`` times; the regions must be the same (boundary lines, obstacle clusters,
grids). Prints per-way medians and, last, ``crop_speedup=<full / cropped>``.

Run: python studies/recorded_lux.py [--frames 20] [--rounds 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.detector.io import ScanSetup
from negobs_gym.detector.io.setup import fields_to_scan
from negobs_gym.detector.loaders import sensor_to_ros_frame
from negobs_gym.detector.traversable import Box, TrackScene, TraversableRegionDetector, synthetic_scan
from negobs_gym.detector.traversable.synthetic import LuxRig
from negobs_gym.sensors.rigs import LUX_FORWARD_M

SCENE = TrackScene(
    left_half_width_m=3.5,
    right_half_width_m=4.5,
    boxes=(Box(x_m=0.5, y_m=9.0, size_x_m=1.0, size_y_m=1.0, height_m=1.0),),
)


def recorded_fields(seed: int) -> dict[str, np.ndarray]:
    """One noisy LUX frame as a driver's cloud: ROS axes, float32, column by column, a layer field."""
    scan = synthetic_scan(
        SCENE, LuxRig(forward_m=LUX_FORWARD_M), range_noise_m=0.02, rng=np.random.default_rng(seed)
    )
    p = np.transpose(scan.points_sensor, (1, 0, 2))  # (columns, layers, 3)
    ok = np.isfinite(p).all(axis=-1)
    layer = np.broadcast_to(np.arange(scan.shape[0])[None, :], ok.shape)[ok]
    x, y, z = sensor_to_ros_frame(p[ok]).astype(np.float32).T
    return {"x": x, "y": y, "z": z, "layer": layer.astype(np.uint16)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    rig = LuxRig(forward_m=LUX_FORWARD_M)
    cropped = ScanSetup(
        sensor="lux",
        azimuth_resolution_deg=0.25,
        translation_m=(0.0, rig.forward_m, rig.height_m),
        rotation=tuple(tuple(float(v) for v in row) for row in rig.rotation),
        columns_centred=True,
        crop_columns=True,
    )
    setups = {"cropped": cropped, "full": dataclasses.replace(cropped, crop_columns=False)}
    clouds = [recorded_fields(k) for k in range(args.frames)]
    scans = {
        way: [fields_to_scan(f, setup, source=f"frame {k}")[0] for k, f in enumerate(clouds)]
        for way, setup in setups.items()
    }
    for way, frames in scans.items():
        print(f"{way}: range image {frames[0].shape[0]} x {frames[0].shape[1]} columns")
    times: dict[str, list[float]] = {way: [] for way in scans}
    regions: dict[str, list] = {}
    for _ in range(args.rounds):
        for way, frames in scans.items():
            detector = TraversableRegionDetector()
            start = time.perf_counter()
            regions[way] = [detector.update(scan, Pose()) for scan in frames]
            times[way].append((time.perf_counter() - start) * 1e3 / len(frames))
    for a, b in zip(regions["cropped"], regions["full"], strict=True):
        assert a.left_line == b.left_line and a.right_line == b.right_line, "boundary lines differ"
        assert len(a.obstacles) == len(b.obstacles), "obstacle clusters differ"
        for name in ("traversable", "positive_obstacles", "feasible", "reachable"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), f"{name} differs"
    print("regions: the same boundary lines, obstacle clusters and grids both ways")
    medians = {way: float(np.median(t)) for way, t in times.items()}
    for way, t in times.items():
        print(f"{way}: median {medians[way]:.2f} ms per frame (rounds {', '.join(f'{v:.2f}' for v in t)})")
    print(f"crop_speedup={medians['full'] / medians['cropped']:.2f}")


if __name__ == "__main__":
    main()
