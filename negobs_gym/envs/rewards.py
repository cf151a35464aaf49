"""Named reward terms; the scalar reward is their weighted sum (weights in RewardConfig)."""

from __future__ import annotations

from negobs_gym.envs.config import RewardConfig
from negobs_gym.sim.events import StepEvents

__all__ = ["reward_terms"]


def reward_terms(
    config: RewardConfig, progress_m: float, events: StepEvents, reached_goal: bool
) -> dict[str, float]:
    """Weighted reward terms of one control step, by name (they sum to the reward)."""
    return {
        "progress": config.progress * progress_m,
        "negative_entry": config.negative_entry * float(bool(events.entered_negative_obstacle)),
        "collision": config.collision * float(bool(events.collision) or events.rollover),
        "time": config.time,
        "goal": config.goal * float(reached_goal),
    }
