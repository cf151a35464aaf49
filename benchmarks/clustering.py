"""Benchmark: paper N's clustering step alone (DBSCAN of the confirmed pairs, one outline each).

The inputs are the confirmed fused pairs of real detector runs: the frames of OffroadNav-v0 with
its default observation (the pure-pursuit driver on the course from seed 0, ``--env-steps``
steps; the frames a training run clusters), the braking-track frames of ``benchmarks/detector.py``
(native rig, 25 km/h, sensor noise) and its dense pit field (100 pits, >= 2,000 candidate pairs a
frame). ``cluster_obstacles`` is then timed on each frame's pairs, ``--rounds`` times over all
frames; each frame's best round counts, and the medians over frames are printed:
``env_cluster_ms=``, ``cluster_ms=`` (braking track) and, as the last line, ``dense_cluster_ms=``.
Run it on two checkouts in turns to compare them; the inputs do not depend on the code being
timed beyond the pairs the detector confirms.

Run: python benchmarks/clustering.py [--env-steps N] [--frames N] [--dense-frames N] [--rounds N]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
from detector import dense_frames, dense_pose, record_frames

import negobs_gym  # noqa: F401  (registers the envs)
from negobs_gym.core.pose import Pose
from negobs_gym.detector import NegativeObstacleDetector, cluster_obstacles
from negobs_gym.drivers import PurePursuitDriver

ENV_ID = "negobs_gym/OffroadNav-v0"


def confirmed_pairs(frames: list[tuple[dict, Pose]]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each frame's confirmed fused pairs (A, B), as ``NegativeObstacleDetector.update`` clusters them."""
    detector = NegativeObstacleDetector()
    out = []
    for scans, pose in frames:
        fused = detector.update(scans, pose).pairs
        out.append((fused.a_m[fused.confirmed], fused.b_m[fused.confirmed]))
    return out


def env_pairs(steps: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """The confirmed fused pairs of ``steps`` OffroadNav-v0 frames, driven along the course."""
    env = gym.make(ENV_ID)

    def episode(seed: int) -> tuple[dict, PurePursuitDriver]:
        _, info = env.reset(seed=seed)
        return info, PurePursuitDriver(env.unwrapped.terrain.track.centreline_xy_m)

    info, driver = episode(seed)
    out = []
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(driver.act(None, info))
        fused = env.unwrapped.perception.detection.pairs
        out.append((fused.a_m[fused.confirmed], fused.b_m[fused.confirmed]))
        if terminated or truncated:
            seed += 1
            info, driver = episode(seed)
    env.close()
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
    parser.add_argument("--env-steps", type=int, default=150, help="OffroadNav-v0 frames")
    parser.add_argument("--frames", type=int, default=25, help="braking-track frames")
    parser.add_argument("--dense-frames", type=int, default=10, help="frames of the dense pit field")
    parser.add_argument("--rounds", type=int, default=5, help="timed calls per frame (the best counts)")
    args = parser.parse_args()
    env = env_pairs(args.env_steps)
    track = confirmed_pairs(record_frames(args.frames))
    dense_field = enumerate(dense_frames(args.dense_frames))
    dense = confirmed_pairs([(scans, dense_pose(k)) for k, scans in dense_field])
    best_ms(env[:3] + track[:3] + dense[:1], 1)  # the compiled kernels load before timing
    for name, inputs in (("env_cluster_ms", env), ("cluster_ms", track), ("dense_cluster_ms", dense)):
        ms, clusters = best_ms(inputs, args.rounds)
        pairs = np.mean([len(a) for a, _ in inputs])
        what = f"{len(inputs)} frames, {pairs:.0f} confirmed pairs, {clusters:.1f} clusters a frame"
        print(f"{name.removesuffix('_ms')}: {what}")
        print(f"{name}={np.median(ms):.2f}")


if __name__ == "__main__":
    main()
