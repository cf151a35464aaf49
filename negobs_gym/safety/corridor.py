"""Nearest hazard along the circular arc swept by the vehicle at a given steering angle."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.core import libm

# Below this curvature [1/m] the path is treated as straight (radius > 1e9 m).
STRAIGHT_CURVATURE_PER_M = 1e-9
# A point on the outer side's line at its entry angle touches the body now; round-off between the
# two angles must not move it a turn later, so angles this close to the entry count as reached [rad].
ENTRY_TOLERANCE_RAD = 1e-9


def hazard_distance_m(
    points_xy_m: np.ndarray,
    steer_rad: float,
    wheelbase_m: float,
    half_width_m: float,
    front_length_m: float = 0.0,
) -> float:
    """Arc length from the origin to the nearest point inside the swept corridor (inf when clear).

    The minimum of :func:`corridor_arcs_m` (see there for the corridor's geometry).
    """
    arcs = corridor_arcs_m(points_xy_m, steer_rad, wheelbase_m, half_width_m, front_length_m)
    return float(np.min(arcs)) if arcs.size else float("inf")


def corridor_arcs_m(
    points_xy_m: np.ndarray,
    steer_rad: float,
    wheelbase_m: float,
    half_width_m: float,
    front_length_m: float = 0.0,
) -> np.ndarray:
    """Arc length (N,) at which the swept corridor reaches each point (inf: never).

    The rear-axle centre follows a circle of radius ``R = wheelbase / tan(steer)`` (kinematic
    bicycle; steer > 0 turns left, towards -X). The corridor is the ring swept by the rectangle of
    half-width ``half_width_m`` reaching ``front_length_m`` ahead of the rear axle (to the front
    bumper): from ``R - half_width`` (the inner rear corner) to ``hypot(R + half_width,
    front_length)`` (the outer front corner, which in a tight turn sweeps up to a metre outside
    the rear-axle band). A point inside is reached at the arc length of its radial projection onto
    the rear-axle circle: the distance convention of the straight path, where a point at ``y``
    ahead is at ``y``. Beyond the outer side (``R + half_width < r``) only the front of the
    rectangle passes, from the angle where its outer side meets radius ``r`` onwards: a point
    beside the car at a smaller angle (beside its outer rear, as when passing a pit in a turn) is
    never reached, as the footprint turns away from it (it counts one turn later). Assumes
    ``R > half_width`` (true for road vehicles). Straight path: points with ``|x| <= half_width``
    and ``y >= 0``, at distance ``y``.
    """
    pts = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
    arcs = np.full(pts.shape[0], np.inf)
    if pts.shape[0] == 0:
        return arcs
    x, y = pts[:, 0], pts[:, 1]
    kappa = math.tan(float(steer_rad)) / wheelbase_m
    if abs(kappa) < STRAIGHT_CURVATURE_PER_M:
        inside = (np.abs(x) <= half_width_m) & (y >= 0.0)
        arcs[inside] = y[inside]
        return arcs
    radius = 1.0 / abs(kappa)
    xm = x if kappa > 0 else -x  # mirror right turns onto left turns
    cx = xm + radius  # vector from the turn centre (-radius, 0) to the point
    r = np.hypot(cx, y)
    inside = (r >= radius - half_width_m) & (r <= math.hypot(radius + half_width_m, front_length_m))
    if not np.any(inside):
        return arcs
    theta = np.mod(libm.arctan2(y[inside], cx[inside]), 2.0 * np.pi)
    outer = radius + half_width_m
    beyond = np.maximum(r[inside] * r[inside] - outer * outer, 0.0)  # 0 within the rear-axle band
    entry = libm.arctan2(np.sqrt(beyond), np.full_like(beyond, outer))  # the outer side meets r here
    theta = np.where(theta >= entry - ENTRY_TOLERANCE_RAD, theta, theta + 2.0 * np.pi)
    arcs[inside] = radius * theta
    return arcs


@dataclass(frozen=True, kw_only=True)
class Corridor:
    """The corridor :func:`hazard_distance_m` searches, as a value: the filter's decision carries it
    (:class:`~negobs_gym.safety.SafetyDecision`), so a frame can draw where the filter looked.

    Attributes:
        steer_rad: Steering angle of the proposed action (> 0 turns left, towards -X).
        wheelbase_m: Kinematic-bicycle wheelbase.
        half_width_m: Half the swept width (body plus the filter's margin).
        front_length_m: Rear axle to front bumper.
    """

    steer_rad: float
    wheelbase_m: float
    half_width_m: float
    front_length_m: float = 0.0

    def hazard_distance_m(self, points_xy_m: np.ndarray) -> float:
        """Arc length to the nearest of ``points_xy_m`` in the corridor (:func:`hazard_distance_m`)."""
        return hazard_distance_m(
            points_xy_m, self.steer_rad, self.wheelbase_m, self.half_width_m, self.front_length_m
        )

    def arcs_m(self, points_xy_m: np.ndarray) -> np.ndarray:
        """Arc length at which the corridor reaches each of ``points_xy_m`` (:func:`corridor_arcs_m`)."""
        return corridor_arcs_m(
            points_xy_m, self.steer_rad, self.wheelbase_m, self.half_width_m, self.front_length_m
        )

    @property
    def _turn(self) -> tuple[float, float]:
        """(radius of the rear-axle circle, +1 left / -1 right); radius inf on a straight path."""
        kappa = math.tan(self.steer_rad) / self.wheelbase_m
        if abs(kappa) < STRAIGHT_CURVATURE_PER_M:
            return math.inf, 1.0
        return 1.0 / abs(kappa), math.copysign(1.0, kappa)

    def reached_at_xy_m(self, arc_m: float) -> np.ndarray:
        """(2, 2) ends of the segment of corridor points :func:`hazard_distance_m` puts at ``arc_m``.

        Straight: across the path at ``y = arc_m``. In a turn: along the radius at the angle
        ``arc_m / R``, from the inner side to the outer front corner's circle, cut where that
        circle's points are not yet reached (the front of the car sweeps them a little later).
        """
        radius, side = self._turn
        h = self.half_width_m
        if math.isinf(radius):
            return np.array([[-h, arc_m], [h, arc_m]])
        theta = arc_m / radius
        outer = radius + h
        r_far = math.hypot(outer, self.front_length_m)
        if theta < math.atan2(self.front_length_m, outer):  # points beyond r = outer / cos(theta) enter later
            r_far = min(r_far, outer / math.cos(theta))
        r = np.array([radius - h, r_far])
        return np.column_stack([side * (r * math.cos(theta) - radius), r * math.sin(theta)])

    def sides_xy_m(self, length_m: float, samples: int = 64) -> np.ndarray:
        """(2, samples, 2) inner and outer side of the rear-axle band over arc lengths 0..``length_m``
        (left then right side on a straight path)."""
        s = np.linspace(0.0, length_m, samples)
        radius, side = self._turn
        if math.isinf(radius):
            xs = np.array([-self.half_width_m, self.half_width_m])
            return np.stack([np.column_stack([np.full_like(s, x), s]) for x in xs])
        theta = s / radius
        rows = []
        for r in (radius - self.half_width_m, radius + self.half_width_m):
            rows.append(np.column_stack([side * (r * np.cos(theta) - radius), r * np.sin(theta)]))
        return np.stack(rows)
