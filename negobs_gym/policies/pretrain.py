"""Warm start: behaviour cloning of a scripted driver before reinforcement learning.

PPO from a random Gaussian policy first has to learn to drive along the route at all: on
OffroadNav-v1 its training return fell from +6 to -50 over the first 16 k steps
(docs/training.md, "from scratch"). The route follower is a solved problem, the
pure-pursuit driver, so :func:`warm_start` first fits the policy's action mean to that driver's
actions (DART-style: the executed action carries Gaussian noise so the demonstrations also show
how to return to the route, while the labels are the driver's clean actions; Laskey et al. 2017),
then sets the policy's action standard deviation to ``action_std`` for PPO's exploration. PPO then
learns what the driver cannot do: leave the route around obstacles.

On OffroadNav-v2, where leaving the track ends the episode, the demonstrator is the
:class:`~negobs_gym.drivers.track_planner.TrackPlannerDriver` instead: it reads the course's
ground-truth obstacles and passes them on the track, which the policy then has to learn from its
grid (``WarmStartConfig.driver``; docs/training.md).

The demonstrations come from the training env itself (same observation wrapper, source and
filter), on seeds of their own (``seed + DEMO_SEED_OFFSET + k``), so neither the training seeds
nor the evaluation seeds are reused.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from negobs_gym.drivers import Driver, make_driver
from negobs_gym.errors import ConfigError, require
from negobs_gym.policies.config import DEMONSTRATORS, WarmStartConfig
from negobs_gym.sim.types import Terrain

__all__ = ["DEMO_SEED_OFFSET", "Demonstrations", "collect_demonstrations", "demonstrator", "warm_start"]

#: Demonstration episodes use seeds ``seed + DEMO_SEED_OFFSET + k`` (training envs use ``seed + i``,
#: evaluations 1,000,000 on).
DEMO_SEED_OFFSET = 500_000


@dataclass(frozen=True)
class Demonstrations:
    """Observations (the wrapped env's dict, stacked) and the driver's clean actions (N, 2)."""

    observations: dict[str, np.ndarray]
    actions: np.ndarray
    episodes: int

    def __add__(self, other: Demonstrations) -> Demonstrations:
        """Both sets, this one's first (DAgger's aggregate)."""
        observations = {k: np.concatenate([v, other.observations[k]]) for k, v in self.observations.items()}
        return Demonstrations(
            observations, np.concatenate([self.actions, other.actions]), self.episodes + other.episodes
        )


def demonstrator(name: str, terrain: Terrain, planner_sight_m: float = 0.0) -> Driver:
    """The scripted driver ``name`` (one of :data:`~negobs_gym.policies.config.DEMONSTRATORS`) for
    one course, with the driver's own defaults (pure pursuit on the centre line; the track planner
    sees ``planner_sight_m`` ahead, 0: the whole course)."""
    if name not in DEMONSTRATORS:
        raise ConfigError("driver", f"unknown demonstrator {name!r}; expected one of {DEMONSTRATORS}")
    return make_driver(name, terrain, planner_sight_m=planner_sight_m)


def collect_demonstrations(
    env: Any,
    steps: int,
    noise_std: float,
    seed: int,
    driver: str = "pure_pursuit",
    policy: Callable[[dict[str, np.ndarray]], np.ndarray] | None = None,
    first_episode: int = 0,
    planner_sight_m: float = 0.0,
) -> Demonstrations:
    """``steps`` steps on ``env`` (a negobs env, possibly wrapped), labelled by the scripted ``driver``.

    Episodes reset on termination or truncation, each on seed ``seed + DEMO_SEED_OFFSET + k`` for
    k = ``first_episode``, ``first_episode + 1``, ...; the executed action is the driver's, or with
    ``policy`` that policy's (DAgger: the learner drives, the driver labels the states it visits),
    plus ``N(0, noise_std)`` noise (from ``default_rng(seed + first_episode)``), clipped to [-1, 1].
    """
    require(isinstance(steps, int) and steps >= 1, "steps", f"must be an int >= 1, got {steps!r}")
    rng = np.random.default_rng(seed + first_episode)
    observations: dict[str, list[np.ndarray]] = {}
    actions: list[np.ndarray] = []
    episodes = 0
    obs, info, expert = None, None, None
    while len(actions) < steps:
        if expert is None:
            obs, info = env.reset(seed=seed + DEMO_SEED_OFFSET + first_episode + episodes)
            expert = demonstrator(driver, env.unwrapped.terrain, planner_sight_m)
            episodes += 1
        label = expert.act(obs, info)
        for key, value in obs.items():
            observations.setdefault(key, []).append(np.array(value, copy=True))
        actions.append(label)
        action = label if policy is None else np.asarray(policy(obs), dtype=np.float64)
        executed = np.clip(action + rng.normal(0.0, noise_std, size=2), -1.0, 1.0).astype(np.float32)
        obs, _, terminated, truncated, info = env.step(executed)
        if terminated or truncated:
            expert = None
    return Demonstrations(
        {key: np.stack(values) for key, values in observations.items()}, np.stack(actions), episodes
    )


def warm_start(model: Any, demos: Demonstrations, config: WarmStartConfig, seed: int = 0) -> list[float]:
    """Fit ``model.policy``'s action mean to ``demos`` (mean squared error), then set its action std.

    Works on SB3 policies with a diagonal Gaussian head and ``log_std`` (PPO, A2C). Returns the
    mean loss of each epoch.

    Raises:
        ConfigError: the policy has no ``log_std`` (SAC's squashed policy is not supported).
    """
    policy = model.policy
    if not hasattr(policy, "log_std"):
        raise ConfigError(
            "algo", f"warm start needs a Gaussian policy with log_std (PPO), got {type(policy).__name__}"
        )
    obs_tensor, _ = policy.obs_to_tensor(demos.observations)
    target = torch.as_tensor(demos.actions, dtype=torch.float32)
    params = [
        p for name, p in policy.named_parameters() if name != "log_std" and not name.startswith("value_net")
    ]
    optimiser = torch.optim.Adam(params, lr=config.learning_rate)
    generator = torch.Generator().manual_seed(seed)
    n = len(target)
    losses = []
    policy.set_training_mode(True)
    for _ in range(config.epochs):
        order = torch.randperm(n, generator=generator)
        total = 0.0
        for start in range(0, n, config.batch_size):
            idx = order[start : start + config.batch_size]
            batch = {key: value[idx] for key, value in obs_tensor.items()}
            mean = policy.get_distribution(batch).distribution.mean
            loss = torch.nn.functional.mse_loss(mean, target[idx])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(idx)
        losses.append(total / n)
    policy.set_training_mode(False)
    with torch.no_grad():
        policy.log_std.fill_(math.log(config.action_std))
    return losses
