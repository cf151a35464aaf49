"""Scripted braking on Braking-v1: cruise at 25 km/h, full brake once the grid shows a ditch close ahead.

Reads only the observation (the ``negative`` grid channel and the speed in ``state``), not the
ground truth; the ground truth in ``info`` is used to report the outcome.

Run: ``python examples/scripted_braking.py [--episodes 5] [--brake-distance 14] [--frames outputs/brake]``
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import gymnasium as gym
import numpy as np

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.spec import ObservationConfig

CRUISE_MPS = 25.0 / 3.6  # paper N §4


def negative_ahead_m(grid: np.ndarray, obs_config: ObservationConfig, half_width_m: float = 1.2) -> float:
    """Distance from the rear axle to the nearest ``negative`` cell in a straight corridor ahead [m]."""
    k = obs_config.channels.index("negative")
    spec, ds = obs_config.grid, obs_config.downsample
    cell = spec.cell_m * ds
    rows, cols = grid.shape[1:]
    y = -spec.back_m + (np.arange(rows) + 0.5) * cell
    x = -spec.side_m + (np.arange(cols) + 0.5) * cell
    hit = grid[k].astype(bool) & (np.abs(x)[None, :] <= half_width_m) & (y[:, None] > 0)
    return float(y[np.nonzero(hit)[0]].min() - 0.5 * cell) if hit.any() else np.inf


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument(
        "--brake-distance", type=float, default=14.0, help="brake when the ditch is this close [m]"
    )
    parser.add_argument("--frames", type=Path, default=None, help="folder for a PNG of each final frame")
    args = parser.parse_args()
    env = gym.make("negobs_gym/Braking-v1", render_mode="rgb_array" if args.frames else None)
    obs_config = env.unwrapped.scenario.observation
    stopped = 0
    for seed in range(args.episodes):
        obs, info = env.reset(seed=seed)
        start_gap = info["distance_to_negative_ahead_m"]
        done = False
        while not done:
            speed = float(obs["state"][0])
            if negative_ahead_m(obs["grid"], obs_config) <= args.brake_distance:
                action = np.array([-1.0, 0.0], np.float32)
            else:
                action = np.array([np.clip(2.0 * (CRUISE_MPS - speed), -1.0, 1.0), 0.0], np.float32)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated or (action[0] == -1.0 and info["speed_mps"] < 0.05)
        entered = bool(info["events"]["entered_negative_obstacle"])
        stopped += not entered
        gap = info["distance_to_negative_ahead_m"]
        print(f"seed={seed} ditch_at={start_gap:.1f}m entered={entered} gap_left={gap:.2f}m")
        if args.frames is not None:
            import matplotlib.pyplot as plt

            args.frames.mkdir(parents=True, exist_ok=True)
            tmp = args.frames / f".braking_{seed}.png.tmp"
            plt.imsave(tmp, env.render(), format="png")
            os.replace(tmp, args.frames / f"braking_{seed}.png")  # atomic write
    env.close()
    print(f"stopped_before={stopped}/{args.episodes}")


if __name__ == "__main__":
    main()
