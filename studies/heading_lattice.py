"""The grid planner with a lattice whose state holds the heading: does planning from the car's
heading, with moves of bounded curvature, keep it on the paths it plans?

``planned_lateral_m`` (:mod:`negobs_gym.drivers.track_planner`) plans over lateral offsets only:
each step's plan starts at the car's place, not its heading, and may turn 0.7 m sideways per
metre at once. Mid-swerve the plan then flips sides from one step to the next while the car drives
on between them (docs/notebook/training_studies.md, "Why it fails"). This study swaps in a lattice
whose state is (lateral offset, last move): a move may change the lateral step by at most
``--bend`` lattice steps from the last one, and the first move starts from the car's heading
relative to the track. Band costs, smoothness and centring are the planner's own. Drives the grid
planner with it through seeds 1,000,000 on (``--first-seed``) at 15 km/h, and prints one line per
drive and ``goal=<k>/<n> ends=<counts>``.

``--filter`` drives behind the scene's filter with the steering search of the docs' grid-planner
evaluations (``filter.steer_search=0.3``, ``filter.margin_m=0``).

Run: python studies/heading_lattice.py [--source oracle] [--downsample 2] [--bend 1] [--seeds 20]
[--first-seed 1000000] [--workers 2] [--filter]
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import functools
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

import negobs_gym.drivers.grid_planner as grid_planner_module
from negobs_gym.core.geometry import vehicle_to_world_xy
from negobs_gym.drivers import make_driver
from negobs_gym.drivers.track_planner import ObstacleBands, TrackPlannerConfig, _add_band_penalty, _car_points
from negobs_gym.envs import make_env
from negobs_gym.eval.episode import STANDSTILL_S, EpisodeStop, drive_episode
from negobs_gym.sim.terrain import track_coordinates
from negobs_gym.sim.types import Terrain

SPEED_MPS = 4.17  # 15 km/h, as the docs' grid-planner evaluations set run.target_speed_mps


def heading_lattice_m(
    terrain: Terrain,
    config: TrackPlannerConfig,
    start_m: tuple[float, float],
    start_slope: float,
    bands: ObstacleBands,
    horizon_m: float,
    bend: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Stations and lateral offsets of a path from ``start_m`` whose first move follows
    ``start_slope`` (lateral metres per metre) and whose moves change by at most ``bend`` lateral
    steps from one station to the next."""
    track = terrain.track
    edge = track.width_m / 2.0 - config.edge_margin_m
    step = config.station_step_m
    first = np.floor(np.clip(start_m[0], 0.0, track.length_m) / step) * step
    last = max(min(track.length_m, first + horizon_m), first + step)
    stations = np.arange(first, last + step, step)
    n_lat = int(np.floor(edge / config.lateral_step_m + 1e-9))
    laterals = np.arange(-n_lat, n_lat + 1) * config.lateral_step_m
    reach = int(np.floor(config.max_slope * step / config.lateral_step_m + 1e-9))
    moves = np.arange(-reach, reach + 1)  # lateral steps per station
    body, axles = _car_points(config)
    checks = [(body, bands.bodies, 1e6), (axles, bands.pits, 1e6), (axles, bands.mounds, config.mound_cost)]
    n = laterals.size
    # [from, move]: the lattice index a move lands on, and whether it stays on the lattice
    to = np.arange(n)[:, None] + moves[None, :]
    valid = (to >= 0) & (to < n)
    to = np.clip(to, 0, n - 1)
    change = laterals[to] - laterals[:, None]
    slope = change / step
    move_cost = np.where(valid, config.smoothness * change**2, np.inf)
    start = int(np.argmin(np.abs(laterals - np.clip(start_m[1], -edge, edge))))
    heading = int(np.clip(np.round(start_slope * step / config.lateral_step_m), -reach, reach))
    # cost[lateral, last move]
    cost = np.full((n, moves.size), np.inf)
    cost[start, heading + reach] = 0.0
    back = np.zeros((stations.size, n, moves.size, 2), dtype=np.intp)
    for i in range(1, stations.size):
        hits = np.zeros(slope.shape)
        for points, obstacle_bands, inside_cost in checks:
            points_lat = laterals[to][:, :, None] + slope[:, :, None] * points  # ahead of the rear axle
            _add_band_penalty(
                hits,
                stations[i] + points,
                points_lat,
                obstacle_bands,
                inside_cost,
                config.soft_cost,
                config.soft_margin_m,
            )
        new = np.full((n, moves.size), np.inf)
        arg = np.zeros((n, moves.size, 2), dtype=np.intp)
        for m in range(moves.size):
            lo, hi = max(0, m - bend), min(moves.size, m + bend + 1)
            best_prev = lo + np.argmin(cost[:, lo:hi], axis=1)  # per from-lattice point
            total = cost[np.arange(n), best_prev] + move_cost[:, m] + hits[:, m]
            rows = np.nonzero(valid[:, m])[0]  # a move lands each from-point on its own point
            new[to[rows, m], m] = total[rows]
            arg[to[rows, m], m, 0] = rows
            arg[to[rows, m], m, 1] = best_prev[rows]
        cost = new + config.centring * laterals[:, None] ** 2
        back[i] = arg
    path = np.empty(stations.size, dtype=np.intp)
    k, m = np.unravel_index(int(np.argmin(cost)), cost.shape)
    path[-1] = k
    for i in range(stations.size - 1, 0, -1):
        k, m = back[i, k, m]
        path[i - 1] = k
    return stations, laterals[path]


def drive(seed: int, env_name: str, overrides: list[str], bend: int, filtered: bool) -> str:
    """The end of one drive of the grid planner on the heading lattice (behind the scene's filter
    when ``filtered``, stopped as ``negobs eval policy`` stops its drives)."""
    env = make_env(env_name, [*overrides, f"run.target_speed_mps={SPEED_MPS}"])
    pose_box: dict[str, Any] = {}

    def planned(terrain, config, start_m, bands, horizon_m):  # the grid planner's call
        pose = pose_box.get("pose")  # none yet at the driver's reset: the start faces the track
        start_slope = 0.0
        if pose is not None:
            ahead = vehicle_to_world_xy(np.array([[0.0, 0.0], [0.0, 1.0]]), pose[:2], float(pose[5]))
            s, lat = track_coordinates(terrain.track, ahead)
            start_slope = float((lat[1] - lat[0]) / max(s[1] - s[0], 1e-3))
        return heading_lattice_m(terrain, config, start_m, start_slope, bands, horizon_m, bend)

    def driver_for(unwrapped: Any) -> Any:
        driver = make_driver(
            "grid_planner",
            unwrapped.terrain,
            target_speed_mps=SPEED_MPS,
            observation=unwrapped.scenario.observation,
        )
        act = driver.act

        def act_with_pose(obs: Any, info: dict[str, Any]) -> np.ndarray:
            pose_box["pose"] = np.asarray(info["pose"], dtype=np.float64)
            return act(obs, info)

        driver.act = act_with_pose
        return driver

    grid_planner_module.planned_lateral_m = planned  # this process drives only this planner
    max_steps = env.spec.max_episode_steps if env.spec and env.spec.max_episode_steps else None
    guard = env.unwrapped.scenario.filter if filtered else False
    stop = EpisodeStop(max_steps=max_steps, standstill_s=STANDSTILL_S)
    with contextlib.closing(env):
        metrics = drive_episode(env, driver_for, seed=seed, filter=guard, stop=stop).metrics()
    ends = [
        name for name in ("goal", "entered", "collision", "trapped", "left_track", "stopped") if metrics[name]
    ]
    return "+".join(ends) or "time_limit"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="offroad_nav_v2")
    parser.add_argument("--source", default="oracle")
    parser.add_argument("--downsample", type=int, default=2)
    parser.add_argument("--bend", type=int, default=1, help="largest change of the lateral step per station")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=1_000_000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--filter", action="store_true", help="behind the steering filter of the docs' evaluations"
    )
    args = parser.parse_args()
    overrides = [f"observation.source={args.source}", f"observation.downsample={args.downsample}"]
    overrides += ["filter.steer_search=0.3", "filter.margin_m=0"]
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    with ProcessPoolExecutor(args.workers) as pool:
        ends = list(
            pool.map(
                functools.partial(
                    drive, env_name=args.env, overrides=overrides, bend=args.bend, filtered=args.filter
                ),
                seeds,
            )
        )
    for seed, end in zip(seeds, ends, strict=True):
        print(f"seed={seed} end={end}")
    goals = sum("goal" in end.split("+") for end in ends)
    print(f"goal={goals}/{len(ends)} ends={dict(collections.Counter(ends))}")


if __name__ == "__main__":
    main()
