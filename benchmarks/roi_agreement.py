"""How far paper N's detector on the ROI rig (the envs' default observation) agrees with the full native rig.

Drives each env (``--env-id``, repeatable; default OffroadNav-v0 and Braking-v0) from ``--seed``
for ``--steps`` control steps (a finished episode is reset with the next seed): ``--driver
constant`` holds half throttle straight ahead, ``--driver route`` follows the course's centreline
with the pure-pursuit driver at 15 km/h (turning drives). At every step both rigs are cast at the
vehicle's true pose with one noise key (so every ray cast by both has the same range), and each
scan stream goes to its own :class:`~negobs_gym.detector.NegativeObstacleDetector` (its own fusion
history). Prints per env:

- ``grid_equal_frames``: frames whose fused obstacle grids are equal, ``cells_differ`` the cells
  set in one grid and not the other, summed over frames;
- ``pairs_in_grid``: the native scan's frame pairs (all sensors) whose B lies in the grid,
  ``missing`` of them the ROI scan does not find, ``extra`` the ROI scan finds and native does not;
- ``rays_per_frame``: rays cast, ROI against native.

Pairs go missing where a bump (paper N §3.1: a rise then a fall of range along one laser) runs
past a laser's cast window: whether a return belongs to a bump depends on the whole ring
(docs/performance.md, "Where the two can differ").

Run: python benchmarks/roi_agreement.py [--env-id negobs_gym/OffroadNav-v0 ...] [--steps 300] [--seed 0]
     [--driver constant|route]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401  (registers the envs)
from negobs_gym.detector import NegativeDetectorConfig, NegativeObstacleDetector
from negobs_gym.drivers import PurePursuitDriver
from negobs_gym.envs.perception import env_rig
from negobs_gym.sensors.lidar import scan_rig
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.roi import HeightEnvelope, RoiConfig, RoiSelector

ACTION = np.array([0.5, 0.0], np.float32)


class _Episode:
    """Both rigs and both detectors for one episode's world and vehicle."""

    def __init__(self, env: gym.Env) -> None:
        u = env.unwrapped
        self.vehicle = u.vehicle
        self.grid = u.config.observation.grid
        self.rig = env_rig("roi")
        self.selector = RoiSelector(self.rig, RoiConfig(region_xy_m=self.grid.extent_xy_m))
        world, exclude = self.vehicle.world, (self.vehicle.body_id,)
        self.caster = make_caster(world, "auto", exclude_body_ids=exclude)
        self.heights = HeightEnvelope(world, exclude_body_ids=exclude)
        self.recent: list = []
        config = NegativeDetectorConfig(grid=self.grid)
        self.roi_detector = NegativeObstacleDetector(config)
        self.native_detector = NegativeObstacleDetector(config)

    def compare(self, frame_seed: int) -> dict[str, int]:
        pose = self.vehicle.true_pose()
        subsets = self.selector.subsets_for_bands(self.heights.bands(pose, self.selector.tiles), self.recent)
        roi = scan_rig(self.rig, self.caster, pose, rng=np.random.default_rng(frame_seed), subsets=subsets)
        native = scan_rig(self.rig, self.caster, pose, rng=np.random.default_rng(frame_seed))
        a = self.roi_detector.update(roi, pose)
        b = self.native_detector.update(native, pose)
        out = {
            "grid_equal": int(np.array_equal(a.grid, b.grid)),
            "cells_differ": int((a.grid != b.grid).sum()),
            "rays_roi": sum(s.size for s in subsets.values()),
            "rays_native": sum(s.ranges_m.size for s in native.values()),
            "pairs": 0,
            "missing": 0,
            "extra": 0,
        }
        for name, pairs in b.frame_pairs.items():
            want, got = self._in_grid(pairs.b_m), self._in_grid(a.frame_pairs[name].b_m)
            out["pairs"] += len(want)
            out["missing"] += len(want - got)
            out["extra"] += len(got - want)
        return out

    def _in_grid(self, points_m: np.ndarray) -> set[tuple[float, ...]]:
        return {tuple(p) for p in points_m[self.grid.cell_of(points_m[:, :2])[2]]}


def _driver(env: gym.Env, kind: str) -> PurePursuitDriver | None:
    return PurePursuitDriver(env.unwrapped.terrain.track.centreline_xy_m) if kind == "route" else None


def agreement(env_id: str, steps: int, seed: int, driver: str = "constant") -> dict[str, int]:
    """Sums of :meth:`_Episode.compare` over ``steps`` control steps of ``env_id``."""
    env = gym.make(env_id)
    _, info = env.reset(seed=seed)
    episode, pilot = _Episode(env), _driver(env, driver)
    totals: dict[str, int] = {}
    next_seed = seed + 1
    for k in range(steps):
        action = ACTION if pilot is None else pilot.act(None, info)
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            _, info = env.reset(seed=next_seed)
            next_seed += 1
            episode, pilot = _Episode(env), _driver(env, driver)
        for key, value in episode.compare(k).items():
            totals[key] = totals.get(key, 0) + value
    env.close()
    totals["frames"] = steps
    totals["episodes"] = next_seed - seed
    return totals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", action="append", help="repeatable (default: OffroadNav-v0, Braking-v0)")
    parser.add_argument("--steps", type=int, default=300, help="control steps per env")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    parser.add_argument("--driver", choices=("constant", "route"), default="constant")
    args = parser.parse_args()
    if args.steps < 1:
        parser.error("--steps must be >= 1")
    env_ids = args.env_id or ["negobs_gym/OffroadNav-v0", "negobs_gym/Braking-v0"]
    for env_id in env_ids:
        t0 = time.perf_counter()
        t = agreement(env_id, args.steps, args.seed, args.driver)
        n = t["frames"]
        share = 100 * t["missing"] / max(1, t["pairs"])
        print(
            f"env={env_id} frames={n} episodes={t['episodes']} grid_equal_frames={t['grid_equal']}/{n} "
            f"cells_differ={t['cells_differ']} pairs_in_grid={t['pairs']} missing={t['missing']} "
            f"({share:.1f} %) extra={t['extra']} "
            f"rays_per_frame roi={t['rays_roi'] / n:.0f} native={t['rays_native'] / n:.0f} "
            f"wall_s={time.perf_counter() - t0:.0f}"
        )


if __name__ == "__main__":
    main()
