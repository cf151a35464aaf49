"""Named reward terms; the scalar reward is their weighted sum (weights in RewardConfig)."""

from __future__ import annotations

from negobs_gym.envs.outcome import StepOutcome
from negobs_gym.spec import RewardConfig

__all__ = ["reward_terms"]


def reward_terms(config: RewardConfig, outcome: StepOutcome, stop_rewarded: bool) -> dict[str, float]:
    """Weighted reward terms of one control step, by name (they sum to the reward).

    ``stop_rewarded`` says the ``stopped`` bonus was already paid this episode (it is paid once).
    """
    ev = outcome.events
    return {
        "progress": config.progress * outcome.progress_m,
        "negative_entry": config.negative_entry * float(bool(ev.entered_negative_obstacle)),
        "collision": config.collision * float(bool(ev.collision) or ev.rollover),
        "time": config.time,
        "goal": config.goal * float(outcome.goal),
        "stopped": config.stopped * float(outcome.stopped_before_hazard and not stop_rewarded),
        "trapped": config.trapped * float(bool(ev.trapped)),
        "off_track": config.off_track * float(outcome.off_track),
        "goal_approach": config.goal_approach * outcome.goal_approach_m,
    }
