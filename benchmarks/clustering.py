"""Benchmark: paper N's clustering step alone (DBSCAN of the confirmed pairs, one outline each).

The inputs are the confirmed fused pairs of real detector runs: the braking-track frames of
``benchmarks/detector.py`` (native rig, 25 km/h, sensor noise) and its dense pit field (100 pits,
>= 2,000 candidate pairs a frame). ``cluster_obstacles`` is then timed on each frame's pairs,
``--rounds`` times over all frames; each frame's best round counts, and the medians over frames
are printed: ``cluster_ms=`` (braking track) and, as the last line, ``dense_cluster_ms=``. Run it
on two checkouts in turns to compare them; the inputs do not depend on the code being timed
beyond the pairs the detector confirms.

Run: python benchmarks/clustering.py [--frames N] [--dense-frames N] [--rounds N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from detector import dense_frames, record_frames

from negobs_gym.core.pose import Pose
from negobs_gym.detector import NegativeObstacleDetector, cluster_obstacles


def confirmed_pairs(frames: list[tuple[dict, Pose]]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each frame's confirmed fused pairs (A, B), as ``NegativeObstacleDetector.update`` clusters them."""
    detector = NegativeObstacleDetector()
    out = []
    for scans, pose in frames:
        fused = detector.update(scans, pose).pairs
        out.append((fused.a_m[fused.confirmed], fused.b_m[fused.confirmed]))
    return out


def best_ms(inputs: list[tuple[np.ndarray, np.ndarray]], rounds: int) -> tuple[np.ndarray, float]:
    """Per frame, the fastest of ``rounds`` calls [ms]; and the mean number of clusters."""
    config = NegativeObstacleDetector().config.clustering
    ms = np.full(len(inputs), np.inf)
    clusters = 0
    for _ in range(rounds):
        for k, (a, b) in enumerate(inputs):
            t = time.perf_counter()
            found = cluster_obstacles(a, b, config)
            ms[k] = min(ms[k], (time.perf_counter() - t) * 1e3)
            clusters += len(found)
    return ms, clusters / (rounds * max(len(inputs), 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=25, help="braking-track frames")
    parser.add_argument("--dense-frames", type=int, default=10, help="frames of the dense pit field")
    parser.add_argument("--rounds", type=int, default=5, help="timed calls per frame (the best counts)")
    args = parser.parse_args()
    track = confirmed_pairs(record_frames(args.frames))
    # creeping forward, as detector.py drives the dense field
    dense_poses = [
        Pose(x=0.0, y=0.05 * k, z=0.0, roll=0.0, pitch=0.0, yaw=0.0) for k in range(args.dense_frames)
    ]
    dense = confirmed_pairs(list(zip(dense_frames(args.dense_frames), dense_poses, strict=True)))
    best_ms(track[:3] + dense[:1], 1)  # the compiled kernels load before timing
    for name, inputs in (("cluster_ms", track), ("dense_cluster_ms", dense)):
        ms, clusters = best_ms(inputs, args.rounds)
        pairs = np.mean([len(a) for a, _ in inputs])
        what = f"{len(inputs)} frames, {pairs:.0f} confirmed pairs, {clusters:.1f} clusters a frame"
        print(f"{name.removesuffix('_ms')}: {what}")
        print(f"{name}={np.median(ms):.2f}")


if __name__ == "__main__":
    main()
