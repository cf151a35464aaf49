"""The grid planner with settings of its own: how far does each get on OffroadNav-v2's courses?

``negobs eval policy grid_planner`` drives :class:`~negobs_gym.drivers.GridPlannerDriver` with its
defaults. This study drives it with any of :class:`~negobs_gym.drivers.GridPlannerConfig`'s
settings changed (``--planner planner.bend_steps=1``, ``--planner
planner.pursuit.lookahead_m=3``, ``--planner memory_steps=0``) through seeds 1,000,000 on
(``--first-seed``) at 15 km/h, and prints one line per drive and ``goal=<k>/<n> ends=<counts>``.
With no ``--planner`` its drives are the eval command's, one for one.

``--filter`` drives behind the scene's filter with the steering search of the docs' grid-planner
evaluations (``filter.steer_search=0.3``, ``filter.margin_m=0``), through ``drive_episode`` and
stopped as ``negobs eval policy`` stops its drives.

Run: python studies/grid_planner_settings.py [--planner KEY.PATH=VALUE ...] [--source detector]
[--downsample 2] [--seeds 20] [--first-seed 1000000] [--workers 2] [--filter]
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import dataclasses
import functools
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from negobs_gym.core.settings import parse_assignment, replace_setting
from negobs_gym.drivers import GridPlannerConfig, GridPlannerDriver
from negobs_gym.drivers.pure_pursuit import PurePursuitConfig
from negobs_gym.envs import make_env
from negobs_gym.eval.episode import STANDSTILL_S, EpisodeStop, drive_episode

SPEED_MPS = 4.17  # 15 km/h, as the docs' grid-planner evaluations set run.target_speed_mps


def planner_config(assignments: list[str]) -> GridPlannerConfig:
    """The grid planner's config at 15 km/h (as ``make_driver`` builds it) with ``assignments``
    (``KEY.PATH=VALUE``) applied in order."""
    config = GridPlannerConfig()
    pursuit = PurePursuitConfig(target_speed_mps=SPEED_MPS)
    config = dataclasses.replace(config, planner=dataclasses.replace(config.planner, pursuit=pursuit))
    for text in assignments:
        keys, value = parse_assignment(text, example="planner.bend_steps=1")
        config = replace_setting(config, keys, value)
    return config


def drive(seed: int, env_name: str, overrides: list[str], config: GridPlannerConfig, filtered: bool) -> str:
    """How one drive of the grid planner with ``config`` ended (behind the scene's filter when
    ``filtered``)."""
    env = make_env(env_name, [*overrides, f"run.target_speed_mps={SPEED_MPS}"])

    def driver_for(unwrapped: Any) -> GridPlannerDriver:
        return GridPlannerDriver(unwrapped.terrain, unwrapped.scenario.observation, config)

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
    parser.add_argument("--source", default="detector")
    parser.add_argument("--downsample", type=int, default=2)
    parser.add_argument(
        "--planner",
        action="append",
        default=[],
        metavar="KEY.PATH=VALUE",
        help="a GridPlannerConfig setting (repeatable), e.g. planner.bend_steps=1",
    )
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=1_000_000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--filter", action="store_true", help="behind the steering filter of the docs' evaluations"
    )
    args = parser.parse_args()
    config = planner_config(args.planner)
    overrides = [f"observation.source={args.source}", f"observation.downsample={args.downsample}"]
    overrides += ["filter.steer_search=0.3", "filter.margin_m=0"]
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    run = functools.partial(
        drive, env_name=args.env, overrides=overrides, config=config, filtered=args.filter
    )
    with ProcessPoolExecutor(args.workers) as pool:
        ends = list(pool.map(run, seeds))
    for seed, end in zip(seeds, ends, strict=True):
        print(f"seed={seed} end={end}")
    goals = sum("goal" in end.split("+") for end in ends)
    print(f"goal={goals}/{len(ends)} ends={dict(collections.Counter(ends))}")


if __name__ == "__main__":
    main()
