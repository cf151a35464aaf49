"""Ground-truth events of a drive (docs/physics.md): negative-obstacle entry, trapped, collision, rollover.

An :class:`EventMonitor` checks the vehicle after every physics step (it registers a step hook on the
world), so a 0.3 m pit cannot slip between two 10 Hz control steps; :meth:`EventMonitor.poll` returns
what happened since the previous poll. The wheel contacts are tested in one vectorised pass against
only the negative obstacles whose bounding boxes hold one of them (a box test over all of a course's
obstacles, cheaper than a spatial index for the tens a course has).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p

from negobs_gym.core.geometry import pad_polygons, points_in_polygons
from negobs_gym.errors import ConfigError, require
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

__all__ = ["EventConfig", "EventMonitor", "StepEvents"]


@dataclass(frozen=True, kw_only=True)
class EventConfig:
    """Thresholds of the event checks.

    Attributes:
        stuck_speed_mps: Below this forward speed [m/s] with throttle applied the vehicle counts as
            not moving.
        stuck_throttle: Minimum throttle (0..1) for "trying to drive".
        stuck_time_s: Not moving while trying to drive this long [s] -> ``trapped``.
        belly_time_s: Chassis touching the ground this long [s] without a break -> ``trapped``.
        trapped_tilt_deg: |roll| or |pitch| above this [deg] (a nose stuck in a trench) -> ``trapped``.
        rollover_tilt_deg: |roll| or |pitch| above this [deg] -> ``rollover``.
    """

    stuck_speed_mps: float = 0.3
    stuck_throttle: float = 0.1
    stuck_time_s: float = 2.0
    belly_time_s: float = 1.0
    trapped_tilt_deg: float = 30.0
    rollover_tilt_deg: float = 60.0

    def __post_init__(self) -> None:
        for name in ("stuck_speed_mps", "stuck_time_s", "belly_time_s"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, name, f"must be > 0, got {value}")
        require(
            math.isfinite(self.stuck_throttle) and 0 < self.stuck_throttle <= 1,
            "stuck_throttle",
            f"must be in (0, 1], got {self.stuck_throttle}",
        )
        for name in ("trapped_tilt_deg", "rollover_tilt_deg"):
            value = getattr(self, name)
            require(math.isfinite(value) and 0 < value < 90, name, f"must be in (0, 90) deg, got {value}")
        require(
            self.trapped_tilt_deg <= self.rollover_tilt_deg,
            "trapped_tilt_deg",
            "must not exceed rollover_tilt_deg",
        )


@dataclass(frozen=True)
class StepEvents:
    """Events since the previous poll.

    Attributes:
        entered_negative_obstacle: Ids of the negative obstacles a wheel's contact patch was inside.
        trapped: The vehicle is stuck (see :class:`EventConfig`); ``trapped_reason`` says why.
        collision: Ids of positive obstacles the vehicle touched.
        rollover: Roll or pitch passed ``rollover_tilt_deg``.
    """

    entered_negative_obstacle: tuple[str, ...] = ()
    trapped: bool = False
    collision: tuple[str, ...] = ()
    rollover: bool = False
    trapped_reason: str | None = None

    @property
    def any(self) -> bool:
        """True when any event happened."""
        return bool(self.entered_negative_obstacle or self.trapped or self.collision or self.rollover)


class _PolygonBoxes:
    """Bounding boxes of polygons: the few polygons that can contain one of a few points."""

    def __init__(self, polygons: np.ndarray) -> None:
        self._lo = polygons.min(axis=1) if len(polygons) else np.zeros((0, 2))
        self._hi = polygons.max(axis=1) if len(polygons) else np.zeros((0, 2))

    def near(self, points_xy: np.ndarray) -> np.ndarray:
        """Indices (ascending) of the polygons whose bounding box holds one of ``points_xy``."""
        lo, hi, pts = self._lo[:, None], self._hi[:, None], points_xy[None]  # (M, 1, 2), (1, P, 2)
        return np.flatnonzero(((lo <= pts) & (pts <= hi)).all(axis=2).any(axis=1))


class EventMonitor:
    """Watches a vehicle after every physics step and accumulates events until :meth:`poll`.

    Args:
        world: The world the vehicle lives in (ground truth comes from ``world.terrain``).
        vehicle: The vehicle to watch.
        config: Thresholds.
    """

    def __init__(self, world: World, vehicle: Vehicle, config: EventConfig | None = None) -> None:
        self.config = config if config is not None else EventConfig()
        if not isinstance(self.config, EventConfig):
            raise ConfigError("config", f"must be an EventConfig, got {type(self.config).__name__}")
        self.world = world
        self.vehicle = vehicle
        negatives = world.terrain.negative_obstacles
        self._neg_ids = np.array([o.obstacle_id for o in negatives], dtype=object)
        self._polygons = pad_polygons(
            [o.outline_xy_m for o in negatives], name="negative_obstacles.outline_xy_m"
        )
        self._near = _PolygonBoxes(self._polygons)
        self._body_to_obstacle = {body: oid for oid, body in world.obstacle_body_ids.items()}
        self._stuck_s = 0.0
        self._belly_s = 0.0
        self.entered_ids: set[str] = set()  # every negative obstacle entered since construction/reset
        self._clear_interval()
        world.add_step_hook(self._check)

    def _clear_interval(self) -> None:
        self._entered: set[str] = set()
        self._collided: set[str] = set()
        self._trapped_reason: str | None = None
        self._rollover = False

    def reset(self) -> None:
        """Forget all accumulated state (call after moving the vehicle to a new start)."""
        self._stuck_s = 0.0
        self._belly_s = 0.0
        self.entered_ids = set()
        self._clear_interval()

    def detach(self) -> None:
        """Stop watching (removes the step hook)."""
        self.world.remove_step_hook(self._check)

    def _check(self) -> None:
        cfg = self.config
        dt = self.world.config.time_step_s
        veh = self.vehicle
        c = self.world.client_id
        if len(self._neg_ids):
            wheels = veh.wheel_contact_xy()
            near = self._near.near(wheels)
            if near.size:
                inside = points_in_polygons(wheels, self._polygons[near]).any(axis=0)
                hits = self._neg_ids[near[inside]].tolist()
                self._entered.update(hits)
                self.entered_ids.update(hits)
        for body, oid in self._body_to_obstacle.items():  # not every contact: the wheels' are most
            if p.getContactPoints(bodyA=veh.body_id, bodyB=body, physicsClientId=c):
                self._collided.add(oid)
        tilt_deg = math.degrees(veh.tilt_rad())
        if tilt_deg > cfg.rollover_tilt_deg:
            self._rollover = True
        throttle = veh.command[0]
        if throttle >= cfg.stuck_throttle and abs(veh.speed_mps()) < cfg.stuck_speed_mps:
            self._stuck_s += dt
        else:
            self._stuck_s = 0.0
        self._belly_s = self._belly_s + dt if veh.chassis_on_ground() else 0.0
        reason = None
        if self._stuck_s >= cfg.stuck_time_s:
            reason = "stuck"
        elif self._belly_s >= cfg.belly_time_s:
            reason = "belly_on_ground"
        elif tilt_deg > cfg.trapped_tilt_deg:
            reason = "tilt"
        if reason is not None:
            self._trapped_reason = reason

    def poll(self) -> StepEvents:
        """Events since the previous poll (or construction); clears the interval's record."""
        self.world.client_id  # noqa: B018 - raises on a closed world
        events = StepEvents(
            entered_negative_obstacle=tuple(sorted(self._entered)),
            trapped=self._trapped_reason is not None,
            collision=tuple(sorted(self._collided)),
            rollover=self._rollover,
            trapped_reason=self._trapped_reason,
        )
        self._clear_interval()
        return events
