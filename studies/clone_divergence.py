"""Where a cloned policy's drive leaves its expert's: the expert labels every state the clone visits.

Drives a saved model (deterministic) through OffroadTrack-v0 courses on the range-limited oracle
grid (``--source detector``: the detector grid), seeds 1,000,000 on (``negobs eval policy``'s),
and at every step asks the track planner
(``--planner-sight-m``, ``--planner-horizon-m``: the expert the clone was fitted to; with a
horizon its label depends only on the car's state and what is in sight) what it would steer
there. Prints one line per episode, then for the failed episodes, in three windows before their
end (the last 10 steps, 30 to 10 steps before, earlier), and for the episodes that reach the goal:
the mean |steering| of expert and clone, their mean |difference|, and on the steps where the
expert steers more than ``--strong`` to one side, the share where the clone steers to the same
side but less, to the other side, and the clone's mean steering towards the expert's side as a
fraction of the expert's (``follows=``). Last line: ``goal=<k>/<n>``.

Run: python studies/clone_divergence.py MODEL [--seeds 30] [--env ENV] [--source oracle|detector]
[--planner-sight-m 14]
[--planner-horizon-m 30] [--strong 0.3]
"""

from __future__ import annotations

import argparse

import numpy as np

from negobs_gym.drivers import make_driver
from negobs_gym.drivers.model import ModelDriver
from negobs_gym.envs import make_env, source_overrides

WINDOWS = (("last 10 steps", -10, None), ("30-10 steps before the end", -30, -10), ("earlier", None, -30))


def drive(model: ModelDriver, env, seed: int, sight_m: float, horizon_m: float) -> tuple[str, np.ndarray]:
    """One episode: its end and the (clone, expert) steering of every step, (T, 2)."""
    obs, info = env.reset(seed=seed)
    expert = make_driver(
        "track_planner", env.unwrapped.terrain, planner_sight_m=sight_m, planner_horizon_m=horizon_m
    )
    steering = []
    terminated = truncated = False
    while not (terminated or truncated):
        label = expert.act(obs, info)
        action = model.act(obs, info)
        steering.append((action[1], label[1]))
        obs, _, terminated, truncated, info = env.step(action)
    end = "goal" if info.get("goal_reached") else "+".join(info["termination"]) or "time_limit"
    return end, np.asarray(steering, dtype=np.float64)


def summary(name: str, steering: np.ndarray, strong: float) -> str:
    clone, expert = steering[:, 0], steering[:, 1]
    hard = np.abs(expert) > strong
    side = np.sign(expert[hard])
    less = np.mean((np.sign(clone[hard]) == side) & (np.abs(clone[hard]) < np.abs(expert[hard])))
    other = np.mean(np.sign(clone[hard]) != side)
    follows = np.mean(clone[hard] * side) / np.mean(np.abs(expert[hard])) if hard.any() else float("nan")
    return (
        f"{name}: steps={len(expert)} expert_abs={np.abs(expert).mean():.2f} "
        f"clone_abs={np.abs(clone).mean():.2f} "
        f"gap={np.abs(clone - expert).mean():.3f} strong_share={hard.mean():.2f} same_side_less={less:.2f} "
        f"other_side={other:.2f} follows={follows:.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", help="a saved SB3 model (e.g. RUN/warm_start.zip)")
    parser.add_argument("--seeds", type=int, default=30, help="courses")
    parser.add_argument("--first-seed", type=int, default=1_000_000)
    parser.add_argument(
        "--env", default="negobs_gym/OffroadTrack-v0", help="env id, shipped scenario or TOML"
    )
    parser.add_argument(
        "--source", choices=("oracle", "detector"), default="oracle", help="the grid the clone drives on"
    )
    parser.add_argument("--planner-sight-m", type=float, default=14.0)
    parser.add_argument("--planner-horizon-m", type=float, default=30.0)
    parser.add_argument("--strong", type=float, default=0.3, help="|expert steering| that counts as strong")
    args = parser.parse_args()
    env = make_env(args.env, source_overrides(args.source))
    model = ModelDriver(args.model)
    episodes = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        end, steering = drive(model, env, seed, args.planner_sight_m, args.planner_horizon_m)
        episodes.append((end, steering))
        gap = np.abs(steering[:, 0] - steering[:, 1])
        print(
            f"seed={seed} end={end} steps={len(steering)} gap={gap.mean():.3f} last10={gap[-10:].mean():.2f}"
        )
    env.close()
    failed = [s for end, s in episodes if end != "goal"]
    for name, lo, hi in WINDOWS:
        if failed:
            print(summary(f"failed, {name}", np.concatenate([s[lo:hi] for s in failed]), args.strong))
    goals = [s for end, s in episodes if end == "goal"]
    if goals:
        print(summary("goal episodes, all steps", np.concatenate(goals), args.strong))
    print(f"goal={len(goals)}/{len(episodes)}")


if __name__ == "__main__":
    main()
