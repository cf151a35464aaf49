"""The hazard protocol: what an env must expose so the braking safety filter can guard it.

Conventions every negobs env follows (and any other env must follow to be filtered):

* Action ``Box(-1, 1, (2,))``: ``action[0]`` longitudinal (throttle > 0, brake < 0, -1 = full
  brake), ``action[1]`` steering (+1 = full LEFT = ``+max_steer_rad``, positive yaw rate).
* Vehicle frame (see ``negobs_gym.core.pose``): Y forward, X right, Z up; origin at the rear-axle
  centre (the INS point). Steering left turns towards -X. Hazard distances are measured from the
  origin along the path; ``front_length_m`` (rear axle to front bumper) widens the corridor to
  what the front corners sweep in a turn.
* Longitudinal model over one control period ``dt_s``: ``v' = max(0, v + dt_s * accel(a0))`` with
  ``accel(a0) = a0 * max_accel_mps2`` for ``a0 >= 0`` and ``a0 * max_brake_decel_mps2`` for
  ``a0 < 0``.
* ``negative_obstacles_xy_m`` holds the vehicle-frame xy of the DETECTED negative-obstacle cells
  (negobs envs fill it from the detector grid, never from ground truth);
  ``positive_obstacles_xy_m`` the same for the grid's positive-obstacle channel (rocks, boxes,
  vehicles), which the filter reads only when ``SafetyFilterConfig.stop_for_positive`` is set.
* Coverage (optional; the ``governed`` filter reads it): ``observed`` is the grid layer of the
  cells holding a LiDAR return in the frame behind the hazard points (in the same vehicle frame),
  ``grid`` its :class:`~negobs_gym.core.grid.GridSpec` and ``pose`` the INS pose of that vehicle
  frame in the world, so the filter can remember cells seen a moment ago.
* Time: ``time_s`` is the env's clock at the decision, ``perception_time_s`` the time the
  sensor data behind ``negative_obstacles_xy_m`` was taken (None when there is no perception
  yet). The filter brakes when that data is missing or older than its
  ``perception_timeout_s`` (fail-safe, as Nav2's collision monitor does with ``source_timeout``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import require
from negobs_gym.safety.decision import SafetyDecision


@dataclass(frozen=True, kw_only=True)
class HazardState:
    """What the safety filter knows at one control step (SI units, vehicle frame)."""

    speed_mps: float  # current forward speed [m/s], >= 0
    negative_obstacles_xy_m: np.ndarray  # (N, 2) detected negative-obstacle points [m]
    vehicle_width_m: float  # [m]
    wheelbase_m: float  # [m]
    max_steer_rad: float  # steering angle at action[1] = +1 [rad]
    dt_s: float  # control period [s]
    max_accel_mps2: float  # acceleration at action[0] = +1 [m/s^2]
    max_brake_decel_mps2: float  # deceleration at action[0] = -1 [m/s^2], > 0
    time_s: float  # env clock at this decision [s]
    perception_time_s: float | None  # when the hazard points were sensed [s]; None = no perception
    # (M, 2) detected positive-obstacle points [m], sensed with the negative ones; empty = none
    positive_obstacles_xy_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    # rear axle to front bumper [m]: the corridor reaches out to the outer front corner's circle in
    # a turn; 0 = the band around the rear-axle arc only
    front_length_m: float = 0.0
    # (rows, cols) bool: cells with a LiDAR return in that frame; None = no coverage reported
    observed: np.ndarray | None = None
    grid: GridSpec | None = None  # the grid `observed` lies on (required with it)
    pose: Pose | None = None  # INS pose of the vehicle frame of the points, world frame

    def __post_init__(self) -> None:
        require(
            np.isfinite(self.speed_mps) and self.speed_mps >= 0,
            "speed_mps",
            f"must be finite and >= 0, got {self.speed_mps!r}",
        )
        for name in ("negative_obstacles_xy_m", "positive_obstacles_xy_m"):
            object.__setattr__(self, name, _points_xy(getattr(self, name), name))
        for name in (
            "vehicle_width_m",
            "wheelbase_m",
            "max_steer_rad",
            "dt_s",
            "max_accel_mps2",
            "max_brake_decel_mps2",
        ):
            value = getattr(self, name)
            require(np.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value!r}")
        require(self.max_steer_rad < np.pi / 2, "max_steer_rad", "must be < pi/2")
        require(
            np.isfinite(self.front_length_m) and self.front_length_m >= 0,
            "front_length_m",
            f"must be finite and >= 0, got {self.front_length_m!r}",
        )
        if self.observed is not None:
            require(isinstance(self.grid, GridSpec), "grid", "must be a GridSpec when observed is given")
            obs = np.asarray(self.observed, dtype=bool)
            shape = self.grid.shape
            require(obs.shape == shape, "observed", f"must have shape {shape}, got {obs.shape}")
            object.__setattr__(self, "observed", obs)
        require(self.pose is None or isinstance(self.pose, Pose), "pose", "must be a Pose or None")
        require(np.isfinite(self.time_s), "time_s", f"must be finite, got {self.time_s!r}")
        if self.perception_time_s is not None:
            require(
                np.isfinite(self.perception_time_s) and self.perception_time_s <= self.time_s,
                "perception_time_s",
                f"must be finite and <= time_s ({self.time_s!r}), got {self.perception_time_s!r}",
            )

    @property
    def perception_age_s(self) -> float:
        """Age of the hazard points [s]; inf when there is no perception."""
        if self.perception_time_s is None:
            return float("inf")
        return float(self.time_s - self.perception_time_s)

    def predicted_speed_mps(self, longitudinal: float) -> float:
        """Speed left after one control period under longitudinal command ``longitudinal``."""
        a0 = float(np.clip(longitudinal, -1.0, 1.0))
        accel = a0 * self.max_accel_mps2 if a0 >= 0 else a0 * self.max_brake_decel_mps2
        return max(0.0, self.speed_mps + self.dt_s * accel)

    def travelled_m(self, v_next_mps: float) -> float:
        """Distance covered during one control period going from ``speed_mps`` to ``v_next_mps``.

        Exact for constant acceleration; when the car stops inside the period it is the stopping
        distance, which the trapezoid over-estimates (conservative).
        """
        return 0.5 * self.dt_s * (self.speed_mps + v_next_mps)


def _points_xy(points: np.ndarray, name: str) -> np.ndarray:
    """``points`` as a finite (N, 2) float array; a ConfigError naming ``name`` otherwise."""
    pts = np.asarray(points, dtype=float)
    if pts.size == 0:
        return np.zeros((0, 2))
    require(pts.ndim == 2 and pts.shape[1] == 2, name, f"must have shape (N, 2), got {pts.shape}")
    require(bool(np.all(np.isfinite(pts))), name, "must be finite (drop unknown cells)")
    return pts


@runtime_checkable
class DecisionSink(Protocol):
    """An env (its ``unwrapped``) that shows the filter's decision, e.g. in its rendered frames."""

    def set_render_overlay(self, decision: SafetyDecision | None) -> None:
        """Show ``decision`` for the coming step (None clears it)."""
        ...


@runtime_checkable
class HazardSource(Protocol):
    """An env (or its ``unwrapped``) the braking safety filter can read hazards from.

    An env whose perception runs slower than its control steps may also tell the oldest its
    hazard data gets in normal running, ``max_perception_age_s`` [s] (NegObsEnv does, with
    ``ObservationConfig.scan_every`` > 1); the filter's ``perception_timeout_s`` counts from there.
    """

    def hazard_state(self) -> HazardState:
        """The current :class:`HazardState` (after ``reset`` or the last ``step``)."""
        ...
