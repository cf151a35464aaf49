"""Long runs do not leak: resident memory over 5,000 steps with resets (slow)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from tests.helpers import HAS_PROC_STATM, rss_mb

WARMUP_STEPS = 1000
STEPS = 5000
MAX_GROWTH_MB = 50.0


@pytest.mark.slow
@pytest.mark.skipif(not HAS_PROC_STATM, reason="needs Linux /proc")
def test_5000_steps_of_offroadnav_default_observation_grow_rss_by_at_most_50_mb():
    env = gym.make("negobs_gym/OffroadNav-v0")
    assert env.unwrapped.scenario.observation.rig == "roi"
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    episodes = 1
    rss_after_warmup = None
    for k in range(STEPS):
        action = np.array([rng.uniform(0.2, 1.0), rng.uniform(-0.5, 0.5)], np.float32)
        _, _, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()
            episodes += 1
        if k + 1 == WARMUP_STEPS:
            rss_after_warmup = rss_mb()
    growth = rss_mb() - rss_after_warmup
    env.close()
    print(f"rss_after_warmup_mb={rss_after_warmup:.1f} growth_mb={growth:.1f} episodes={episodes}")
    assert episodes >= 5, "the run must cross several resets"
    assert growth <= MAX_GROWTH_MB, f"RSS grew {growth:.1f} MB after warm-up over {episodes} episodes"
