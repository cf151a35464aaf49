"""How far the detected negative cells reach beyond the true pits, beside and ahead of the car.

The safety filter stops a car for any detected negative cell in its corridor (the footprint widened
by ``SafetyFilterConfig.margin_m``); a driver passing a pit at arm's length meets the part of the
detected outline that lies outside the pit. This drives the track planner (ground truth, 14 m of
sight, the OffroadTrack-v0 clones' expert) without the filter through ``--seeds`` courses of
``--env`` and, every ``--every`` steps, takes the cells the filter would read
(``hazard_state().negative_obstacles_xy_m``, the detector grid's 0.2 m cells) within 3 m of the
car's axis from the rear axle to 12 m ahead. A cell outside every true pit outline *overhangs* by
its distance to the nearest outline; cells more than 3 m from any pit are false detections and not
counted. Reported beside the car (rear axle to 4 m ahead) and ahead (4-12 m).

Prints one line per course, one per region (cells, share outside the pits, overhang p50 / p90 /
p99 / max), then, last, ``overhang_p90_m=<beside> <ahead>``. ``--set
observation.tighten_pairs=false`` measures paper N's fusion history (docs/detector_features.md,
"Near edge").

Run: python studies/outline_overhang.py [--seeds 6] [--first-seed 3000020]
[--env offroad_nav_v2_structure] [--every 2] [--set KEY.PATH=VALUE]
"""

from __future__ import annotations

import argparse

import numpy as np

from negobs_gym.cli.common import add_set_option, task_env_or_exit
from negobs_gym.core.geometry import (
    distance_to_polyline,
    pad_polygons,
    points_in_polygons,
    vehicle_to_world_xy,
)
from negobs_gym.drivers import PurePursuitConfig, TrackPlannerConfig, TrackPlannerDriver
from negobs_gym.envs import make_env

NEAR_PIT_M = 3.0  # farther from every pit: a false detection, not an overhang
REGIONS = {"beside": (-1.0, 4.0), "ahead": (4.0, 12.0)}  # y ahead of the rear axle [m]
HALF_WIDTH_M = 3.0  # |x| of the cells looked at [m]


def overhangs(cells_xy: np.ndarray, outlines: list[np.ndarray]) -> np.ndarray:
    """Per world cell: 0 inside a pit, else its distance to the nearest outline (inf: none)."""
    inside = points_in_polygons(cells_xy, pad_polygons(outlines)).any(axis=1)
    closed = [np.vstack([o, o[:1]]) for o in outlines]
    distance = np.min([distance_to_polyline(cells_xy, c, NEAR_PIT_M) for c in closed], axis=0)
    distance[distance > NEAR_PIT_M] = np.inf  # beyond it only known to exceed it
    return np.where(inside, 0.0, distance)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="offroad_nav_v2_structure", help="env id, shipped scenario or TOML")
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--first-seed", type=int, default=3_000_020)
    parser.add_argument("--every", type=int, default=2, help="sample every N-th step")
    parser.add_argument("--max-steps", type=int, default=320)
    add_set_option(parser)
    args = parser.parse_args()
    task_env_or_exit(parser, args.env, None, args.overrides).close()  # a bad --env or --set: exit 2
    planner = TrackPlannerConfig(sight_m=14.0, plan_horizon_m=30.0, pursuit=PurePursuitConfig())
    found: dict[str, list[np.ndarray]] = {name: [] for name in REGIONS}
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        env = make_env(args.env, args.overrides)
        obs, info = env.reset(seed=seed)
        task = env.unwrapped
        driver = TrackPlannerDriver(task.terrain, planner)
        outlines = [np.asarray(o.outline_xy_m) for o in task.terrain.negative_obstacles]
        for step in range(args.max_steps):
            obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
            if terminated or truncated:
                break
            cells = task.hazard_state().negative_obstacles_xy_m
            if step % args.every or not outlines or len(cells) == 0:
                continue
            pose = np.asarray(info["pose"], dtype=np.float64)
            over = overhangs(vehicle_to_world_xy(cells, pose[:2], pose[5]), outlines)
            for name, (y0, y1) in REGIONS.items():
                region = (np.abs(cells[:, 0]) < HALF_WIDTH_M) & (cells[:, 1] >= y0) & (cells[:, 1] < y1)
                found[name].append(over[region & np.isfinite(over)])
        env.close()
        print(f"seed={seed} steps={step + 1} goal={int(bool(info.get('goal_reached', False)))}", flush=True)
    p90 = {}
    for name, parts in found.items():
        values = np.concatenate(parts) if parts else np.zeros(0)
        out = values[values > 0]
        share = out.size / max(values.size, 1)
        q = np.percentile(out, [50, 90, 99]) if out.size else np.full(3, np.nan)
        p90[name] = q[1]
        print(
            f"{name}: cells={values.size} outside={share:.2f} overhang_m p50={q[0]:.2f} p90={q[1]:.2f} "
            f"p99={q[2]:.2f} max={out.max() if out.size else np.nan:.2f}"
        )
    print(f"overhang_p90_m={p90['beside']:.2f} {p90['ahead']:.2f}")


if __name__ == "__main__":
    main()
