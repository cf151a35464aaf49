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
- ``corridor_differ``: (frame, steer) pairs, over 21 steering commands from full left to full
  right, where the braking-safety filter's hazard distance (Eq. 18's ``d``: the nearest negative
  cell in the swept corridor, ``negobs_gym.safety.hazard_distance_m``) differs between the two
  grids, and ``nearest_differing_m`` the nearer of the two distances over those pairs; the filter
  can decide differently only where that distance is within reach of the braking distance
  (``r_25kmh_m``, ``R`` at 25 km/h);
- ``rays_per_frame``: rays cast, ROI against native, and ``in_grid``: the native rays whose return
  lies in the grid (LUX included). No exact selection casts fewer: it is the floor that even a
  selection knowing every return beforehand would cast, before the features' neighbourhoods.

Pairs go missing where a bump (paper N §3.1: a rise then a fall of range along one laser) runs
past a laser's cast window: whether a return belongs to a bump depends on the whole ring
(docs/notebook/performance.md, "Where the two can differ").

Run: python studies/roi_agreement.py [--env-id negobs_gym/OffroadNav-v0 ...] [--steps 300] [--seed 0]
     [--driver constant|route]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401  (registers the envs)
from negobs_gym.detector import FusionConfig, NegativeDetectorConfig, NegativeObstacleDetector
from negobs_gym.drivers import PurePursuitDriver
from negobs_gym.envs.perception import env_rig
from negobs_gym.eval.detection_campaign import BRAKING_SPEED_MPS
from negobs_gym.safety import SafetyFilterConfig, braking_distance_m, hazard_distance_m
from negobs_gym.sensors.lidar import scan_rig
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.roi import HeightEnvelope, RoiConfig, RoiSelector

ACTION = np.array([0.5, 0.0], np.float32)
STEER_FAN = np.linspace(-1.0, 1.0, 21)  # action[1] values whose corridors are compared


class _Episode:
    """Both rigs and both detectors for one episode's world and vehicle."""

    def __init__(self, env: gym.Env) -> None:
        u = env.unwrapped
        self.vehicle = u.vehicle
        self.grid = u.scenario.observation.grid
        self.rig = env_rig("roi")
        self.selector = RoiSelector(self.rig, RoiConfig(region_xy_m=self.grid.extent_xy_m))
        world, exclude = self.vehicle.world, (self.vehicle.body_id,)
        self.caster = make_caster(world, "auto", exclude_body_ids=exclude)
        self.heights = HeightEnvelope(world, exclude_body_ids=exclude)
        self.recent: list = []
        # the env's own detector settings: its grid and whether its fusion tightens pairs
        tighten = FusionConfig(tighten_on_match=u.scenario.observation.tighten_pairs)
        config = NegativeDetectorConfig(grid=self.grid, fusion=tighten)
        self.roi_detector = NegativeObstacleDetector(config)
        self.native_detector = NegativeObstacleDetector(config)
        car = self.vehicle.config
        self.wheelbase_m = car.wheelbase_m
        self.half_width_m = 0.5 * (car.width_m + SafetyFilterConfig().margin_m)
        self.steers_rad = STEER_FAN * np.radians(car.max_steer_deg)

    def compare(self, frame_seed: int) -> dict[str, float]:
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
            "rays_in_grid": sum(
                int(self.grid.cell_of(s.points_vehicle[..., :2])[2].sum()) for s in native.values()
            ),
            "pairs": 0,
            "missing": 0,
            "extra": 0,
            "corridor_differ": 0,
            "nearest_differing_m": np.inf,
        }
        if out["cells_differ"]:
            centres = self.grid.cell_centres()
            for steer in self.steers_rad:
                d = [
                    hazard_distance_m(centres[g], steer, self.wheelbase_m, self.half_width_m)
                    for g in (a.grid, b.grid)
                ]
                if d[0] != d[1]:
                    out["corridor_differ"] += 1
                    out["nearest_differing_m"] = min(out["nearest_differing_m"], *d)
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


def agreement(env_id: str, steps: int, seed: int, driver: str = "constant") -> dict[str, float]:
    """Sums of :meth:`_Episode.compare` over ``steps`` control steps of ``env_id`` (the least
    ``nearest_differing_m``)."""
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
            if key == "nearest_differing_m":
                totals[key] = min(totals.get(key, np.inf), value)
            else:
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
            f"({share:.1f} %) extra={t['extra']} corridor_differ={t['corridor_differ']} "
            f"nearest_differing_m={t['nearest_differing_m']:.1f} "
            f"r_25kmh_m={braking_distance_m(BRAKING_SPEED_MPS):.1f} "
            f"rays_per_frame roi={t['rays_roi'] / n:.0f} native={t['rays_native'] / n:.0f} "
            f"in_grid={t['rays_in_grid'] / n:.0f} "
            f"wall_s={time.perf_counter() - t0:.0f}"
        )


if __name__ == "__main__":
    main()
