"""Weights of an episode's named reward terms (``[reward]`` of a scenario spec)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from negobs_gym.errors import require

__all__ = ["RewardConfig"]


@dataclass(frozen=True, kw_only=True)
class RewardConfig:
    """Weights of the named reward terms (summed into the scalar reward).

    Attributes:
        progress: Per metre of progress along the track.
        negative_entry: Once, when a wheel enters a negative obstacle.
        collision: Once, on contact with a positive obstacle or a rollover.
        time: Per control step (a small cost of time).
        goal: Once, on reaching the goal.
        stopped: Once, on coming to a stop before a negative obstacle (the braking task; see
            ``TaskSpec.stop_window_m`` in :mod:`negobs_gym.spec.scenario`).
        trapped: Once, when the vehicle is trapped (stuck with its wheels spinning, e.g. against a
            bank; ``sim.events``). Default 0: then being trapped costs only the progress not made,
            which is less than an entry costs, so a learner that cannot pass an obstacle learns to
            drive into the bank (docs/training.md).
        off_track: Per step that ends with the car's centre off the track (``StepOutcome.off_track``;
            once on OffroadTrack-v0, where that ends the episode). Default 0: then leaving the track
            costs only the progress not made, and PPO on v2 learns to leave it rather than risk
            an entry (docs/notebook/training_studies.md).
        goal_approach: Per metre the car's straight-line distance to the goal shrinks within
            ``goal_approach_radius_m`` of it (negative when it grows): a potential-based shaping
            term (Ng et al. 1999), so it pays nothing for circling and does not change which
            policy is best. Default 0. The progress term pays for metres along the centre line
            wherever across the track they are driven, so a learner that passes beside the
            goal circle earns all of it but the goal; this term points the last metres at the
            goal (docs/training.md).
        goal_approach_radius_m: Where ``goal_approach`` starts paying [m from the goal].
    """

    progress: float = 1.0
    negative_entry: float = -100.0
    collision: float = -100.0
    time: float = -0.01
    goal: float = 50.0
    stopped: float = 0.0
    trapped: float = 0.0
    off_track: float = 0.0
    goal_approach: float = 0.0
    goal_approach_radius_m: float = 15.0

    def __post_init__(self) -> None:
        terms = (
            "progress",
            "negative_entry",
            "collision",
            "time",
            "goal",
            "stopped",
            "trapped",
            "off_track",
            "goal_approach",
        )
        for name in terms:
            v = getattr(self, name)
            require(isinstance(v, (int, float)) and math.isfinite(v), name, f"must be finite, got {v!r}")
        r = self.goal_approach_radius_m
        require(
            isinstance(r, (int, float)) and math.isfinite(r) and r > 0,
            "goal_approach_radius_m",
            f"must be finite and > 0, got {r!r}",
        )
