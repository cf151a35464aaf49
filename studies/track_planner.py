"""The track planner against centre-line pure pursuit on OffroadTrack-v0 courses (ground-truth expert).

Drives ``TrackPlannerDriver`` (:mod:`negobs_gym.drivers.track_planner`: a path planned around the
course's ground-truth obstacles, on the track, followed by pure pursuit at 15 km/h) and
``PurePursuitDriver`` on the centre line through the same courses (``--speed-kmh`` sets both
drivers' cruise speed; a scenario runs them at its spec's; ``--planner-sight-m`` limits what the
planner sees ahead; ``--planner-horizon-m`` makes it plan again at every step), seeds 1,000,000
on (the evaluation seeds of ``negobs eval policy``), on the range-limited oracle grid (the drivers
read ``info``, not the grid, so the grid source only sets the cost). Prints one line per episode
and per driver ``<driver> goal=<k>/<n> ends=<termination counts> mean_progress_m=<m>
wall_s=<s>``; the planner's line is last.

Run: python studies/track_planner.py [--seeds 60] [--first-seed 1000000] [--speed-kmh 25]
[--planner-sight-m 14] [--planner-horizon-m 30]
"""

from __future__ import annotations

import argparse
import collections
import time

from negobs_gym.drivers import make_driver
from negobs_gym.envs import make_env
from negobs_gym.policies.config import DEMONSTRATORS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=60, help="courses")
    parser.add_argument("--first-seed", type=int, default=1_000_000)
    parser.add_argument("--env", default="negobs_gym/OffroadTrack-v0")
    parser.add_argument("--speed-kmh", type=float, default=None, help="cruise speed (default: the drivers')")
    parser.add_argument(
        "--planner-sight-m", type=float, default=0.0, help="planner's sight ahead (0: the whole course)"
    )
    parser.add_argument(
        "--planner-horizon-m",
        type=float,
        default=0.0,
        help="> 0: the planner plans again at every step this far ahead (0: one path, replanned)",
    )
    args = parser.parse_args()
    env = make_env(args.env, ["observation.source=oracle"])
    for name in DEMONSTRATORS:
        begin, ends, progress = time.perf_counter(), collections.Counter(), []
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            obs, info = env.reset(seed=seed)
            speed = None if args.speed_kmh is None else args.speed_kmh / 3.6
            driver = make_driver(
                name,
                env.unwrapped.terrain,
                target_speed_mps=speed,
                planner_sight_m=args.planner_sight_m,
                planner_horizon_m=args.planner_horizon_m,
            )
            terminated = truncated = False
            while not (terminated or truncated):
                obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
            end = "+".join(info["termination"]) or "time_limit"
            ends[end] += 1
            progress.append(info["station_m"])
            print(f"{name} seed={seed} end={end} station_m={info['station_m']:.1f}", flush=True)
        counts = ",".join(f"{k}:{v}" for k, v in sorted(ends.items()))
        print(
            f"{name} goal={ends['goal']}/{args.seeds} ends={counts} "
            f"mean_progress_m={sum(progress) / len(progress):.1f} wall_s={time.perf_counter() - begin:.0f}"
        )
    env.close()


if __name__ == "__main__":
    main()
