"""Train PPO (MultiInputPolicy on the grid + state observation) on a negobs env, vectorized.

Run::

    python examples/train_ppo.py --env-id negobs_gym/Braking-v1 --steps 20000 --envs 4 --out outputs/ppo
    python examples/train_ppo.py --filter ...   # wrap each env in the Eq. 18 braking safety filter

The model is saved to ``<out>/ppo_<env>_<filter|nofilter>.zip`` and evaluated on 5 seeded
episodes (mean return and how many episodes entered a negative obstacle are printed).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np


def make_env(env_id: str, use_filter: bool):
    """Thunk building one env (optionally behind the braking safety filter) in any process."""

    def thunk() -> gym.Env:
        env = gym.make(f"negobs_gym:{env_id}")  # "module:id" registers the envs in subprocesses
        if use_filter:
            from negobs_gym.safety import BrakingSafetyFilter

            env = BrakingSafetyFilter(env)
        return env

    return thunk


def evaluate(model, env_id: str, use_filter: bool, episodes: int = 5) -> tuple[float, int]:
    """Mean return and number of negative-obstacle entries over ``episodes`` seeded episodes."""
    env = make_env(env_id, use_filter)()
    returns, entries = [], 0
    for seed in range(episodes):
        obs, _ = env.reset(seed=10_000 + seed)
        total, done = 0.0, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total += reward
            entries += bool(info["events"]["entered_negative_obstacle"])
            done = terminated or truncated
        returns.append(total)
    env.close()
    return float(np.mean(returns)), entries


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="negobs_gym/Braking-v1")
    parser.add_argument("--steps", type=int, default=20_000, help="total environment steps")
    parser.add_argument("--envs", type=int, default=2, help="parallel environments (SubprocVecEnv)")
    parser.add_argument("--filter", action="store_true", help="wrap envs in BrakingSafetyFilter")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("outputs/ppo"))
    args = parser.parse_args()

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = SubprocVecEnv([make_env(args.env_id, args.filter) for _ in range(args.envs)])
    venv.seed(args.seed)
    model = PPO("MultiInputPolicy", venv, n_steps=256, batch_size=64, seed=args.seed, device="cpu", verbose=1)
    model.learn(total_timesteps=args.steps)
    venv.close()
    args.out.mkdir(parents=True, exist_ok=True)
    tag = "filter" if args.filter else "nofilter"
    path = args.out / f"ppo_{args.env_id.split('/')[-1]}_{tag}.zip"
    model.save(path)  # SB3 writes the zip itself
    mean_return, entries = evaluate(PPO.load(path, device="cpu"), args.env_id, args.filter)
    print(f"saved={path} mean_return={mean_return:.2f} negative_entries={entries}/5")


if __name__ == "__main__":
    main()
