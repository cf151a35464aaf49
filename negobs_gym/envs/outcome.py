"""What happened in one control step, and the termination rules a scenario spec names."""

from __future__ import annotations

from dataclasses import dataclass

from negobs_gym.sim.events import StepEvents

__all__ = ["StepOutcome", "termination_conditions"]


@dataclass(frozen=True, kw_only=True)
class StepOutcome:
    """One control step as the reward and termination hooks see it (ground truth, for the env).

    Attributes:
        events: Physics events since the previous step.
        progress_m: Distance gained along the track centre line [m].
        goal: Within the task's goal radius of the goal.
        stopped: Standing (below the task's stop speed) for the task's hold time, with no
            negative-obstacle entry this episode.
        stopped_before_hazard: ``stopped`` with a negative obstacle at most the task's stop window
            ahead of the bumper.
        off_track: The rear-axle centre is beyond the track's half width from the centre line.
        goal_approach_m: How much the straight-line distance to the goal, capped at the reward's
            ``goal_approach_radius_m``, shrank this step [m] (negative when it grew).
    """

    events: StepEvents
    progress_m: float = 0.0
    goal: bool = False
    stopped: bool = False
    stopped_before_hazard: bool = False
    off_track: bool = False
    goal_approach_m: float = 0.0


def termination_conditions(outcome: StepOutcome) -> dict[str, bool]:
    """Every termination rule by the name a spec's ``terminations`` uses, and whether it fired."""
    ev = outcome.events
    return {
        "entered_negative_obstacle": bool(ev.entered_negative_obstacle),
        "trapped": bool(ev.trapped),
        "collision": bool(ev.collision),
        "rollover": bool(ev.rollover),
        "goal": outcome.goal,
        "stopped": outcome.stopped,
        "off_track": outcome.off_track,
    }
