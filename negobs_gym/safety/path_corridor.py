"""Nearest hazard along a planned path: the corridor a driver's plan sweeps, not its current arc.

Eq. 18 needs the distance d the car can still travel before a hazard. Along the arc of the
proposed steering (:func:`~negobs_gym.safety.corridor.hazard_distance_m`) a car steering round a
pit is measured into the pit whenever its steering at that instant points there (full lock in the
middle of a swerve). A driver that plans its path (the track planner, pure pursuit along a route)
can hand the filter that path instead; the corridor is then what the footprint sweeps along it.
"""

from __future__ import annotations

import numpy as np

from negobs_gym.errors import ConfigError

PLAN_STEP_M = 0.1  # spacing of the poses sampled along the path [m]
PLAN_REACH_M = 40.0  # the path is extended straight along its last segment to this length [m]


def resample_path(path_xy_m: np.ndarray, step_m: float, reach_m: float) -> tuple[np.ndarray, ...]:
    """Poses every ``step_m`` along the polyline from the origin (the rear axle now) through
    ``path_xy_m``, extended straight on to ``reach_m``: stations (K,), positions (K, 2) and unit
    tangents (K, 2), vehicle frame.

    Raises:
        ConfigError: a path that is not finite (N, 2).
    """
    path = np.asarray(path_xy_m, dtype=float)
    if path.ndim != 2 or path.shape[1] != 2 or not np.all(np.isfinite(path)):
        raise ConfigError("path_xy_m", f"must be finite with shape (N, 2), got shape {path.shape}")
    vertices = np.vstack([np.zeros((1, 2)), path])
    seg = np.diff(vertices, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    keep = length > 1e-9
    if not np.any(keep):  # no direction given: straight ahead
        seg, length = np.array([[0.0, 1.0]]), np.array([1.0])
        vertices = np.array([[0.0, 0.0], [0.0, 1.0]])
    else:
        seg, length = seg[keep], length[keep]
        vertices = np.vstack([np.zeros((1, 2)), np.cumsum(seg, axis=0)])
    tangent = seg / length[:, None]
    total = float(length.sum())
    if total < reach_m:  # straight on along the last segment
        tangent = np.vstack([tangent, tangent[-1:]])
        vertices = np.vstack([vertices, vertices[-1] + tangent[-1] * (reach_m - total)])
        length = np.append(length, reach_m - total)
    starts = np.concatenate([[0.0], np.cumsum(length)])
    stations = np.arange(0.0, min(reach_m, starts[-1]) + 0.5 * step_m, step_m)
    index = np.clip(np.searchsorted(starts, stations, side="right") - 1, 0, len(length) - 1)
    positions = vertices[index] + tangent[index] * (stations - starts[index])[:, None]
    return stations, positions, tangent[index]


def path_hazard_distance_m(
    points_xy_m: np.ndarray,
    path_xy_m: np.ndarray,
    half_width_m: float,
    front_length_m: float = 0.0,
    *,
    step_m: float = PLAN_STEP_M,
    reach_m: float = PLAN_REACH_M,
) -> float:
    """Distance along the planned rear-axle path to the nearest point its footprint covers (inf
    when none within ``reach_m``).

    ``path_xy_m`` (N, 2), vehicle frame (X right, Y forward, origin the rear axle now): the points
    the rear-axle centre is to pass through, in order; the path runs from the origin through them
    and straight on past the last. The footprint at each pose sampled every ``step_m`` is the
    rectangle ``|x'| <= half_width_m``, ``0 <= y' <= front_length_m`` in the pose's frame (rear axle
    to front bumper). A point it covers is at the station where the rear axle next comes abreast
    of it (``y' = 0``, within ``half_width_m + front_length_m`` of the path), from the first pose
    that covers it on: the convention of :func:`~negobs_gym.safety.corridor.hazard_distance_m`,
    where a point ``y`` straight ahead is at ``y`` and a point the front sweeps in a turn at its
    radial projection. A covered point the path leaves before coming abreast (it turns away) is
    at the station of first cover plus how far ahead of the rear axle it was covered.
    """
    pts = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
    if pts.shape[0] == 0:
        return float("inf")
    stations, positions, tangents = resample_path(path_xy_m, step_m, reach_m)
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    reach_across = half_width_m + front_length_m
    near = np.all((pts >= lo - reach_across - step_m) & (pts <= hi + reach_across + step_m), axis=1)
    pts = pts[near]
    if pts.shape[0] == 0:
        return float("inf")
    rel = pts[None, :, :] - positions[:, None, :]  # (K, M, 2)
    ahead = rel[..., 0] * tangents[:, None, 0] + rel[..., 1] * tangents[:, None, 1]
    across = np.abs(rel[..., 0] * tangents[:, None, 1] - rel[..., 1] * tangents[:, None, 0])
    half_step = 0.5 * step_m
    covered = (across <= half_width_m) & (ahead >= -half_step) & (ahead <= max(front_length_m, half_step))
    hit = np.any(covered, axis=0)
    if not np.any(hit):
        return float("inf")
    ahead, across, covered = ahead[:, hit], across[:, hit], covered[:, hit]
    first = np.argmax(covered, axis=0)  # (M,) first covering pose
    poses = np.arange(len(stations))[:, None]
    # within a step either way: off the path the along-track coordinate moves faster than the station
    abreast = (np.abs(ahead) <= step_m) & (across <= reach_across) & (poses >= first[None, :])
    columns = np.arange(ahead.shape[1])
    at = np.where(np.any(abreast, axis=0), np.argmax(abreast, axis=0), first)
    distance = stations[at] + ahead[at, columns]
    distance = distance[distance >= 0.0]  # not behind the rear axle now
    return float(np.min(distance)) if distance.size else float("inf")
