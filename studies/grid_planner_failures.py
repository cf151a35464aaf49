"""Why the grid planner fails on a grid: a gap drawn shut, an obstacle not drawn or too small, or neither.

Drives ``grid_planner`` (:mod:`negobs_gym.drivers.grid_planner`: the track planner's lattice
around the blobs of the env's ``grid`` observation) without a filter (``--filter``: behind the
scene's, a drive ending ``stopped`` once the car stands still for 1 s, as the eval's drives do)
through seeds 1,000,000 on (``negobs eval policy``'s evaluation seeds) at 15 km/h, and at every
step compares its picture
with the ground truth over the same 20 m horizon (:func:`~negobs_gym.drivers.track_planner.blocked_moves`):

- ``picture_free``: the path it planned is free of the bands it planned around;
- ``truth_free``: the ground-truth planner, with the grid planner's clearances, finds a free path
  from where the car is, around the obstacles that begin within 20 m;
- ``hits_truth``: the path it planned runs into the ground-truth band of an obstacle that
  begins within ``--near-m`` (8 m: at 15 km/h Eq. 18's braking distance is 7.4 m, so this is what
  the car meets next; farther ones may not be in the grid's range yet, the oracle's 14 m), and
  if so whether the picture drew it at all (a band of the same kind overlapping its band).

Each drive that misses the goal is put down to its last ``--window`` steps (4 s at 10 Hz):
``no_gap`` when the truth had no free path in at least half of them; ``closed`` when the picture
had none in half of them while the truth had one (the grid drew a gap shut: outlines wider than
the obstacles, false alarms); else, where its path ran into the truth while the picture showed
it free, ``narrow`` when the obstacle it ran into was drawn (too small or misplaced to keep the
car off it) and ``unseen`` when it was not drawn (missed, or drawn too late), whichever held in
more steps; else ``other``: the path it followed was clear of what it met next, yet the car
ran in or was trapped (it left the path: the lattice plans from the car's place, not its
heading, so mid-swerve its plan flips sides from one step to the next; with ``--set
run.driver_settings.planner.bend_steps=1`` it plans from the heading, and so does the ground-truth
planner it is compared with). Prints one line per drive and
``failures=<n> closed=<k> unseen=<k> narrow=<k> no_gap=<k> other=<k> goal=<k>/<n>``.

Run: python studies/grid_planner_failures.py [--env offroad_nav_v2] [--source detector]
[--downsample 4] [--seeds 20] [--first-seed 1000000] [--near-m 8] [--workers 2] [--filter]
[--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import collections
import functools
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from negobs_gym.drivers.track_planner import (
    ObstacleBands,
    TrackPlannerConfig,
    blocked_moves,
    planned_lateral_m,
    track_state,
)
from negobs_gym.envs import make_env
from negobs_gym.eval.episode import STANDSTILL_S, EpisodeStop
from negobs_gym.eval.scenario_runner import make_driver
from negobs_gym.safety import BrakingSafetyFilter

SPEED_MPS = 4.17  # 15 km/h, as the docs' grid-planner evaluations set run.target_speed_mps


def drive(seed: int, env_name: str, overrides: list[str], window: int, near_m: float, filtered: bool) -> dict:
    """One drive of the grid planner on ``seed`` and the cause of its end (behind the scene's
    filter when ``filtered``, ended as ``stopped`` once the car stands still for
    ``STANDSTILL_S``, as ``negobs eval policy`` ends its drives)."""
    env = make_env(env_name, [*overrides, f"run.target_speed_mps={SPEED_MPS}"])
    if filtered:
        env = BrakingSafetyFilter(env, config=env.unwrapped.scenario.filter)
    stop = EpisodeStop(standstill_s=STANDSTILL_S)
    still_s, dt = 0.0, 1.0 / env.unwrapped.scenario.episode.control_hz
    obs, info = env.reset(seed=seed)
    terrain = env.unwrapped.terrain
    driver = make_driver("grid_planner", env.unwrapped.scenario, terrain)  # with run.driver_settings
    planner = driver.config.planner
    truth = ObstacleBands.of(terrain, planner)
    horizon = planner.plan_horizon_m
    steps: list[tuple[bool, bool, bool, bool]] = []
    terminated = truncated = False
    while not (terminated or truncated):
        action = driver.act(obs, info)
        station, lateral, slope = track_state(terrain.track, np.asarray(info["pose"]))
        seen = truth.seen(station + horizon)
        path = driver.path_m
        ideal = planned_lateral_m(
            terrain, planner, (station, lateral), bands=seen, horizon_m=horizon, start_slope=slope
        )
        hit = _hit_bands(path, truth.seen(station + near_m), planner)
        steps.append(
            (
                blocked_moves(*path, driver.bands, planner) == 0,
                blocked_moves(*ideal, seen, planner) == 0,
                bool(hit),
                all(_overlaps(band, getattr(driver.bands, kind)) for kind, band in hit),
            )
        )
        obs, _, terminated, truncated, info = env.step(action)
        still_s = still_s + dt if info["speed_mps"] < stop.standstill_mps else 0.0
        if still_s >= stop.standstill_s:
            break
    end = "+".join(info["termination"]) or ("stopped" if still_s >= stop.standstill_s else "time_limit")
    picture_free, truth_free, hits_truth, hit_drawn = np.array(steps[-window:]).T
    hidden = picture_free & hits_truth
    if "goal" in info["termination"]:
        cause = "-"
    elif np.mean(~truth_free) >= 0.5:
        cause = "no_gap"
    elif np.mean(~picture_free & truth_free) >= 0.5:
        cause = "closed"
    elif hidden.any():
        cause = "narrow" if np.sum(hidden & hit_drawn) > np.sum(hidden & ~hit_drawn) else "unseen"
    else:
        cause = "other"
    return {
        "seed": seed,
        "end": end,
        "cause": cause,
        "closed_steps": int(np.sum(~picture_free & truth_free)),
        "unseen_steps": int(np.sum(hidden & ~hit_drawn)),
        "narrow_steps": int(np.sum(hidden & hit_drawn)),
        "no_gap_steps": int(np.sum(~truth_free)),
    }


def _hit_bands(
    path: tuple[np.ndarray, np.ndarray], bands: ObstacleBands, planner: TrackPlannerConfig
) -> list[tuple[str, np.ndarray]]:
    """The (kind, band) of ``bands``' pits and bodies that the path runs into."""
    hit = []
    for kind in ("pits", "bodies"):
        for band in getattr(bands, kind):
            alone = {"pits": np.empty((0, 4)), "bodies": np.empty((0, 4)), "mounds": np.empty((0, 4))}
            alone[kind] = band[None]
            if blocked_moves(*path, ObstacleBands(**alone, lead_m=bands.lead_m), planner):
                hit.append((kind, band))
    return hit


def _overlaps(band: np.ndarray, others: np.ndarray) -> bool:
    """Whether the (s0, s1, l0, l1) ``band`` overlaps any of ``others``."""
    s0, s1, l0, l1 = band
    return bool(
        np.any((others[:, 0] <= s1) & (others[:, 1] >= s0) & (others[:, 2] <= l1) & (others[:, 3] >= l0))
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="offroad_nav_v2")
    parser.add_argument("--source", default="detector")
    parser.add_argument("--downsample", type=int, default=4, help="grid cells of 0.2 m x this")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=1_000_000)
    parser.add_argument("--window", type=int, default=40, help="last steps a failure is judged on")
    parser.add_argument(
        "--near-m",
        type=float,
        default=8.0,
        help="a path's hits count on obstacles that begin this close ahead",
    )
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scenario override")
    parser.add_argument(
        "--filter",
        action="store_true",
        help="behind the scene's filter (--set filter.KEY=VALUE to change it)",
    )
    args = parser.parse_args()
    overrides = [f"observation.source={args.source}", f"observation.downsample={args.downsample}", *args.set]
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    with ProcessPoolExecutor(args.workers) as pool:
        drives = list(
            pool.map(
                functools.partial(
                    drive,
                    env_name=args.env,
                    overrides=overrides,
                    window=args.window,
                    near_m=args.near_m,
                    filtered=args.filter,
                ),
                seeds,
            )
        )
    for row in drives:
        print(" ".join(f"{key}={value}" for key, value in row.items()))
    causes = collections.Counter(row["cause"] for row in drives)
    goals = sum("goal" in row["end"].split("+") for row in drives)
    failures = len(drives) - goals
    summary = " ".join(
        f"{cause}={causes[cause]}" for cause in ("closed", "unseen", "narrow", "no_gap", "other")
    )
    print(f"failures={failures} {summary} goal={goals}/{len(drives)}")


if __name__ == "__main__":
    main()
