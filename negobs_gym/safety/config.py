"""Settings of the braking safety filter: plain data, so a scenario spec can hold them (its
``[filter]`` table) without importing the filter itself."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from negobs_gym.errors import require
from negobs_gym.safety.braking import BrakingConfig

__all__ = ["FILTER_MODES", "SafetyFilterConfig", "filter_config"]

#: Filter modes: paper N's Eq. 18 veto braking fully (``brake``) or to the largest safe command
#: (``cap_speed``), or Eq. 18 plus the speed governor (``governed``, docs/safety.md).
FILTER_MODES = ("brake", "cap_speed", "governed")


@dataclass(frozen=True, kw_only=True)
class SafetyFilterConfig:
    """Settings of :class:`BrakingSafetyFilter` (Eq. 18 constants plus the corridor margin, and
    the speed governor's settings, read in ``mode="governed"`` only)."""

    braking: BrakingConfig = field(default_factory=BrakingConfig)
    margin_m: float = 0.4  # added to the vehicle width for the corridor (engineering choice) [m]
    mode: Literal["brake", "cap_speed", "governed"] = "brake"  # FILTER_MODES; paper N: brake
    # Oldest hazard data the filter acts on [s], beyond the age the env's frames reach between two
    # of them (its max_perception_age_s, 0 when it scans every step); older or missing -> full
    # brake. Not in paper N: two periods of its 10 Hz LiDAR / control loop, so one late frame
    # (jitter) is tolerated and a second is not (at 25 km/h the car covers 1.4 m in 0.2 s that no
    # scan has looked at).
    perception_timeout_s: float = 0.2
    # Hysteresis after a veto [m]: until an action passes again, it must keep this much more than
    # R(v'). Not in paper N: without it a driver pushing against the filter creeps on at d ~ R(0) = B,
    # stop and go every other step (seen in scenario runs), and never stands still before the hazard.
    release_margin_m: float = 1.0
    # Also stop for the grid's positive-obstacle cells (rocks, boxes, vehicles) with the same
    # Eq. 18 test. Not in paper N, whose filter guards negative obstacles; off by default. Useful
    # with the structure channel, which sees rocks and boxes 2-20 m ahead (docs/detector_structure.md).
    stop_for_positive: bool = False
    # -- the speed governor (mode "governed"; not in paper N: the assured-clear-distance rule) --
    # Kept free beyond R(v') inside the observed clear distance [m]: room for the detector's
    # confirmation frames (Eq. 16 needs a pit seen in several) before a hazard at the edge of
    # the clear ground turns into a detected one.
    governor_margin_m: float = 1.0
    # Lowest speed limit the governor sets [m/s] while the car can still stop with its front
    # bumper creep_clearance_m short of the clear distance's end: it creeps over a crest to look
    # behind it, and stops at the edge of what it has seen (a pit's near rim hides the pit: its
    # cells hold no returns).
    creep_speed_mps: float = 1.5
    # While creeping, the front bumper stops at least this short of the first unobserved or
    # hazard cell [m]: creeping, the test is v'^2/(2 mu g) + v' T_r + (rear axle to bumper) +
    # this <= clear - travelled, Eq. 18 with the buffer B shrunk to the car's own nose.
    creep_clearance_m: float = 1.0
    # Cells without a LiDAR return end the clear distance (behind a crest or bank, past the
    # rings); False: only hazard cells and the grid's range do.
    unobserved_blocks: bool = True
    # Cells observed this long ago still count as observed, carried with the INS pose [s]: the
    # rings sweep the ground as the car moves, and the rig's blind disc was seen a moment ago.
    coverage_memory_s: float = 1.0
    # Keep the negative-obstacle points read in the world frame of the INS pose until their cell
    # is observed clear again (a return this frame, no hazard), any mode. Not in paper N, whose
    # filter reads each frame alone: its detector can drop a pit whose rim enters the HDL-64's
    # blind disc (docs/safety.md, "Hazard memory").
    hazard_memory: bool = False
    # With hazard_memory: a remembered point within this distance of the rear axle is kept even
    # where its cell is observed clear [m]. Not in paper N: its detector needs a pit's near rim and
    # far wall in the rings, so closing in it loses the pairs (a 3 m pit: 195 pit points 8 m ahead,
    # 37 at 6 m) while the pit's cells still return, and memory would release them as the car
    # drives up (docs/safety.md, "Hazard memory"). 0: every cell seen clear releases its points
    hazard_memory_hold_m: float = 0.0
    # Largest change of the steering command (action units, 1 = full lock) the filter may make
    # ahead of a veto: when the proposed steering's corridor passes Eq. 18 but not with
    # steer_lead_s of travel to spare, it takes the nearest steering within this change, in steps
    # of steer_search_step, whose corridor passes with that lead (the smaller change first; at
    # equal change the longer hazard distance); an action failing Eq. 18 itself is vetoed as
    # paper N's filter does. Not in paper N, whose filter only brakes (0: never steers). A
    # minimal-intervention shield: passing a pit in a bend, the arc of a steering a little tighter
    # than needed sweeps its drawn rim, and a veto stops the car beside it (docs/safety.md,
    # "Steering search").
    steer_search: float = 0.0
    steer_search_step: float = 0.05  # spacing of the steering commands tried [action units]
    # How far ahead of Eq. 18's boundary the search steers, as travel time at v' [s]: the car's
    # yaw rate builds up over 0.1-0.7 s at 25 km/h (more for more steering), so a steering found
    # at the boundary itself is not driven before the pit is inside the stopping distance
    # (docs/safety.md, "Steering search").
    steer_lead_s: float = 1.0

    def __post_init__(self) -> None:
        require(
            isinstance(self.braking, BrakingConfig),
            "braking",
            f"must be a BrakingConfig, got {type(self.braking).__name__}",
        )
        require(
            np.isfinite(self.perception_timeout_s) and self.perception_timeout_s > 0,
            "perception_timeout_s",
            f"must be finite and > 0, got {self.perception_timeout_s!r}",
        )
        require(
            np.isfinite(self.release_margin_m) and self.release_margin_m >= 0,
            "release_margin_m",
            f"must be finite and >= 0, got {self.release_margin_m!r}",
        )
        require(
            np.isfinite(self.margin_m) and self.margin_m >= 0,
            "margin_m",
            f"must be finite and >= 0, got {self.margin_m!r}",
        )
        require(self.mode in FILTER_MODES, "mode", f"must be one of {FILTER_MODES}, got {self.mode!r}")
        for name in ("stop_for_positive", "unobserved_blocks", "hazard_memory"):
            value = getattr(self, name)
            require(isinstance(value, bool), name, f"must be a bool, got {value!r}")
        require(
            isinstance(self.steer_search, (int, float)) and 0.0 <= self.steer_search <= 2.0,
            "steer_search",
            f"must be within [0, 2] (action units), got {self.steer_search!r}",
        )
        for name in ("steer_search_step", "steer_lead_s"):  # steer_lead_s 0 would leave the search idle
            value = getattr(self, name)
            ok = isinstance(value, (int, float)) and np.isfinite(value) and value > 0
            require(ok, name, f"must be finite and > 0, got {value!r}")
        for name in (
            "governor_margin_m",
            "creep_speed_mps",
            "creep_clearance_m",
            "coverage_memory_s",
            "hazard_memory_hold_m",
        ):
            value = getattr(self, name)
            require(
                isinstance(value, (int, float)) and np.isfinite(value) and value >= 0,
                name,
                f"must be finite and >= 0, got {value!r}",
            )


def filter_config(setting: bool | SafetyFilterConfig) -> SafetyFilterConfig | None:
    """The filter a run asks for: a :class:`SafetyFilterConfig` as it is, any true flag (``True``,
    ``np.True_``, 1) the defaults, a false one None (no filter)."""
    if isinstance(setting, SafetyFilterConfig):
        return setting
    return SafetyFilterConfig() if setting else None
