"""The braking safety filter's decision for one step, as a typed record."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from negobs_gym.safety.corridor import Corridor

#: Why the filter changed an action: a detected hazard inside R(v) (Eq. 18), missing or old
#: hazard data, the governor's speed cap with the observed clear distance ending at an
#: unobserved cell ("unobserved") or at the grid's range or a hazard beyond R(v) ("governor"),
#: or a steering nearby whose corridor passes Eq. 18 where the proposed one failed ("steered").
Reason = Literal["hazard", "stale_data", "unobserved", "governor", "steered"]


@dataclass(frozen=True, kw_only=True, eq=False)
class SafetyDecision:
    """What :class:`~negobs_gym.safety.BrakingSafetyFilter` decided for one step.

    Attributes:
        vetoed: The proposed action was replaced.
        hazard_distance_m: Arc length to the nearest detected hazard in the corridor (inf = clear).
        braking_distance_m: R(v) at the current speed (Eq. 18).
        speed_mps: The current forward speed v the decision was made at (>= 0).
        safe_speed_mps: Largest v with R(v) <= hazard distance.
        original_action: The action proposed (float32, shape (2,)).
        applied_action: The action passed to the env.
        perception_age_s: Age of the hazard data at the decision [s] (inf = no perception).
        perception_stale: The hazard data was missing or older than the filter's timeout, so the
            filter braked whatever the distance.
        hazard_channel: Which grid channel the nearest hazard came from: ``"negative"``,
            ``"positive"`` (only with ``stop_for_positive``), or None when the corridor is clear.
        corridor: Where the filter looked for hazards (the proposed steering's swept corridor, in
            the vehicle frame at decision time); None in a decision made without one.
        reason: Why the action was changed (:data:`Reason`), None when it passed unchanged.
        governed: The governor capped the speed (``mode="governed"``); ``vetoed`` stays False
            for a cap alone: it is no Eq. 18 veto.
        steered: The proposed steering passed Eq. 18 but not with ``steer_lead_s`` to spare, and
            the filter applied a steering within ``steer_search`` whose corridor passes with it;
            ``vetoed`` is False, and ``hazard_distance_m`` and ``corridor`` are the applied
            steering's.
        clear_distance_m: The observed clear distance along the corridor [m] (governed mode;
            NaN otherwise).
        clear_end: What ended it: ``"hazard"``, ``"unobserved"`` or ``"range"`` (None outside
            governed mode).
        speed_limit_mps: The governor's speed limit for the coming step: the largest v' whose
            R(v') plus its margin fits the clear distance left after the step, or a creep that
            stops with the front bumper short of its end, whichever is larger [m/s] (inf
            outside governed mode).
    """

    vetoed: bool
    hazard_distance_m: float
    braking_distance_m: float
    speed_mps: float
    safe_speed_mps: float
    original_action: np.ndarray
    applied_action: np.ndarray
    perception_age_s: float
    perception_stale: bool
    hazard_channel: Literal["negative", "positive"] | None = None
    corridor: Corridor | None = None
    reason: Reason | None = None
    governed: bool = False
    steered: bool = False
    clear_distance_m: float = float("nan")
    clear_end: Literal["hazard", "unobserved", "range"] | None = None
    speed_limit_mps: float = float("inf")

    @property
    def cost(self) -> float:
        """1.0 when vetoed or when the vehicle already violates d < R(v), else 0.0 (safe-RL cost)."""
        return 1.0 if (self.vetoed or self.hazard_distance_m < self.braking_distance_m) else 0.0

    def as_dict(self) -> dict[str, Any]:
        """Plain dict for ``info["safety"]`` (arrays copied)."""
        return {
            "vetoed": self.vetoed,
            "hazard_distance_m": self.hazard_distance_m,
            "braking_distance_m": self.braking_distance_m,
            "speed_mps": self.speed_mps,
            "safe_speed_mps": self.safe_speed_mps,
            "original_action": self.original_action.copy(),
            "applied_action": self.applied_action.copy(),
            "perception_age_s": self.perception_age_s,
            "perception_stale": self.perception_stale,
            "hazard_channel": self.hazard_channel,
            "corridor": self.corridor,
            "reason": self.reason,
            "governed": self.governed,
            "steered": self.steered,
            "clear_distance_m": self.clear_distance_m,
            "clear_end": self.clear_end,
            "speed_limit_mps": self.speed_limit_mps,
        }
