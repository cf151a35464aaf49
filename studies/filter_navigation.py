"""The track planner behind the braking safety filter: how often the filter lets a navigating car through.

Drives the expert the OffroadTrack-v0 clones were fitted to (``track_planner`` with
``--planner-sight-m`` and ``--planner-horizon-m``; it reads the course's ground-truth obstacles;
``--wheel-clearance-m`` and ``--clearance-m`` widen the berth it keeps from pits and bodies)
through ``--env`` (default ``offroad_nav_v2_structure``) on seeds ``--first-seed`` on, without
the filter (``--filter off``) or behind ``BrakingSafetyFilter`` (paper N Eq. 18 on the detector
grid; ``--stop-for-positive`` also stops for the positive channel, ``--mode cap_speed`` caps the
speed instead of braking, ``--margin-m`` replaces the corridor's margin, ``--buffer-m`` B).
Prints one line per course (goal, entered, collision, left the track, vetoes, steps, and the
channel and hazard distance of the first veto), then ``goal=<k>/<n> entries= collisions=
left_track= vetoes=``.

Run: python studies/filter_navigation.py [--seeds 20] [--first-seed 3000020]
[--filter off|on] [--stop-for-positive] [--mode brake|cap_speed] [--margin-m 0.4] [--buffer-m 5]
[--wheel-clearance-m 0.4] [--clearance-m 0.3]
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from negobs_gym.cli.common import add_set_option, task_env_or_exit
from negobs_gym.drivers import PurePursuitConfig, TrackPlannerConfig, TrackPlannerDriver
from negobs_gym.envs import make_env
from negobs_gym.eval.braking_campaign import run_driven_episode
from negobs_gym.safety import BrakingConfig, SafetyFilterConfig


class TrackPlanner:
    """The track planner, built on the course the env has just reset to."""

    def __init__(self, env: Any, config: TrackPlannerConfig) -> None:
        self.env, self.config = env, config
        self.driver = None
        self.first_veto = ("-", math.nan)

    def reset(self, seed: int) -> None:
        self.driver = None
        self.first_veto = ("-", math.nan)

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        if self.driver is None:
            self.driver = TrackPlannerDriver(self.env.unwrapped.terrain, self.config)
            self.driver.reset(0)
        safety = info.get("safety")
        if safety is not None and safety["vetoed"] and self.first_veto[0] == "-":
            self.first_veto = (safety["hazard_channel"], safety["hazard_distance_m"])
        return self.driver.act(obs, info)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="offroad_nav_v2_structure", help="env id, shipped scenario or TOML")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=3_000_020)
    parser.add_argument("--filter", choices=("off", "on"), default="on")
    parser.add_argument("--stop-for-positive", action="store_true")
    parser.add_argument("--mode", choices=("brake", "cap_speed"), default="brake", help="what a veto applies")
    parser.add_argument(
        "--margin-m", type=float, default=SafetyFilterConfig().margin_m, help="corridor margin [m]"
    )
    parser.add_argument("--buffer-m", type=float, default=BrakingConfig().buffer_m, help="B of Eq. 18 [m]")
    parser.add_argument("--planner-sight-m", type=float, default=14.0)
    parser.add_argument("--planner-horizon-m", type=float, default=30.0)
    defaults = TrackPlannerConfig()
    parser.add_argument("--wheel-clearance-m", type=float, default=defaults.wheel_clearance_m)
    parser.add_argument("--clearance-m", type=float, default=defaults.clearance_m)
    parser.add_argument("--max-steps", type=int, default=600)
    add_set_option(parser)
    args = parser.parse_args()
    task_env_or_exit(parser, args.env, None, args.overrides).close()  # a bad --env or --set: exit 2
    guard: bool | SafetyFilterConfig = False
    if args.filter == "on":
        guard = SafetyFilterConfig(
            braking=BrakingConfig(buffer_m=args.buffer_m),
            stop_for_positive=args.stop_for_positive,
            mode=args.mode,
            margin_m=args.margin_m,
        )
    planner = TrackPlannerConfig(
        sight_m=args.planner_sight_m,
        plan_horizon_m=args.planner_horizon_m,
        wheel_clearance_m=args.wheel_clearance_m,
        clearance_m=args.clearance_m,
        pursuit=PurePursuitConfig(),
    )
    totals = dict.fromkeys(("goal", "entered", "collision", "left_track", "vetoes"), 0)
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        env = make_env(args.env, args.overrides)
        driver = TrackPlanner(env, planner)
        m = run_driven_episode(env, driver, seed, guard, args.max_steps)
        env.close()
        for k in totals:
            totals[k] += int(m[k])
        channel, distance = driver.first_veto
        print(
            f"seed={seed} goal={int(m['goal'])} entered={int(m['entered'])} collision={int(m['collision'])} "
            f"left_track={int(m['left_track'])} vetoes={m['vetoes']} steps={m['steps']} "
            f"first_veto={channel}@{distance:.2f}m",
            flush=True,
        )
    print(
        f"goal={totals['goal']}/{args.seeds} entries={totals['entered']} collisions={totals['collision']} "
        f"left_track={totals['left_track']} vetoes={totals['vetoes']}"
    )


if __name__ == "__main__":
    main()
