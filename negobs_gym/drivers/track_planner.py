"""A privileged expert: pure pursuit along a path planned around the ground-truth obstacles.

The pure-pursuit driver follows the centre line and so drives into the first obstacle of every
``winding_course`` (~25 m). :class:`TrackPlannerDriver` reads the terrain's ground truth instead of
any sensor: :func:`planned_lateral_m` finds, by dynamic programming over track stations and
lateral offsets, a path on the track that keeps the car's body off the positive obstacles and its
wheels out of the negative ones (docs/notebook/training_studies.md, "Towards a policy for OffroadNav-v2").
It is the demonstrator for OffroadTrack-v0's warm start (:mod:`negobs_gym.policies.pretrain`) and a
reference for what staying on the track while passing every obstacle takes; it is not a
perception-driven baseline. Its clearances suit its pursuit's default 15 km/h: at 25 km/h the
follower lags the path and reaches 2 of 20 goals instead of 19 (docs/notebook/training_studies.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from negobs_gym.core.geometry import vehicle_to_world_xy
from negobs_gym.drivers.pure_pursuit import PurePursuitConfig, PurePursuitDriver
from negobs_gym.errors import require
from negobs_gym.sim.terrain import track_coordinates
from negobs_gym.sim.types import Terrain, Track

__all__ = [
    "ObstacleBands",
    "TrackPlannerConfig",
    "TrackPlannerDriver",
    "blocked_moves",
    "planned_lateral_m",
    "track_state",
]


@dataclass(frozen=True, kw_only=True)
class TrackPlannerConfig:
    """Car body, clearances and lattice of the planner (papers silent).

    The body defaults are the envs' car (:class:`~negobs_gym.sim.vehicle.VehicleConfig`: 4.5 x 2 m,
    0.85 m rear overhang); the path is the rear axle's, as pure pursuit steers it.
    """

    length_m: float = 4.5  # body length [m]
    half_width_m: float = 1.0  # half the body's width [m]
    rear_overhang_m: float = 0.85  # rear bumper behind the rear axle [m]
    wheelbase_m: float = 2.8  # rear to front axle [m]
    half_track_m: float = 0.8  # axle centre to a wheel's contact patch, sideways [m]
    clearance_m: float = 0.3  # kept between the body's side and a positive obstacle [m]
    wheel_clearance_m: float = 0.4  # kept between a wheel and a negative obstacle's rim [m]
    lead_m: float = 0.5  # bands start this far before an obstacle, for the follower's lag [m]
    soft_margin_m: float = 1.0  # beyond a band, closeness costs up to soft_cost over this width [m]
    soft_cost: float = 50.0  # cost per point at a band's edge, falling quadratically to 0
    mound_cost: float = 1000.0  # per wheel on a mound: drivable, but the car may stall on top
    edge_margin_m: float = 0.2  # the rear axle's centre stays this far inside the track edge [m]
    max_slope: float = 0.7  # largest lateral change per metre of station (~35 degrees)
    smoothness: float = 20.0  # cost per (lateral change [m])^2 between lattice stations
    centring: float = 0.05  # cost per m^2 of lateral offset at each lattice station
    station_step_m: float = 0.5  # lattice spacing along the track [m]
    lateral_step_m: float = 0.1  # lattice spacing across the track [m]
    # plan again from the car's own station and offset once it is this far off the path [m]
    # (0: plan once); DAgger needs labels from states the path never visits
    replan_deviation_m: float = 0.5
    # plan with only the obstacles that begin within this distance ahead of the rear axle, and
    # again as each new one comes into sight (0: the whole course); 14 m is the range-limited
    # oracle grid's, so the expert knows no more than the policy it labels for [m]
    sight_m: float = 0.0
    # > 0: plan again at every step from the car's station and offset, this far ahead (0: one
    # path to the end of the track, planned again only as above). The label is then a function of
    # where the car is and what is in sight, which is all a clone can learn (DAgger's expert);
    # a whole-course path remembers the state it was planned from [m]
    plan_horizon_m: float = 0.0
    # > 0: the lattice's state holds the last move as well as the offset, and each move's
    # sideways step may differ from the last one's by at most this many lateral steps (bounded
    # curvature), the first move's from the car's heading; a plan made mid-swerve then carries the
    # swerve on instead of flipping sides (docs/notebook/training_studies.md, "Why it fails"). 0: the
    # state is the offset only, and any move up to max_slope may follow any other
    bend_steps: int = 0
    pursuit: PurePursuitConfig = field(default_factory=PurePursuitConfig)

    def __post_init__(self) -> None:
        positive = ("length_m", "half_width_m", "wheelbase_m", "half_track_m", "max_slope")
        for name in (*positive, "station_step_m", "lateral_step_m"):
            value = getattr(self, name)
            require(np.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value!r}")
        non_negative = ("rear_overhang_m", "clearance_m", "wheel_clearance_m", "lead_m", "soft_margin_m")
        non_negative += (
            "soft_cost",
            "mound_cost",
            "edge_margin_m",
            "smoothness",
            "centring",
            "replan_deviation_m",
            "sight_m",
            "plan_horizon_m",
        )
        for name in non_negative:
            value = getattr(self, name)
            require(np.isfinite(value) and value >= 0, name, f"must be finite and >= 0, got {value!r}")
        require(self.rear_overhang_m < self.length_m, "rear_overhang_m", "must be < length_m")
        bend = self.bend_steps
        require(
            isinstance(bend, int) and not isinstance(bend, bool) and bend >= 0,
            "bend_steps",
            f"must be an int >= 0, got {bend!r}",
        )


def _track_band(terrain: Terrain, outline_xy_m: np.ndarray, widen_m: float, lead_m: float) -> np.ndarray:
    """(s0, s1, l0, l1): the station and lateral extent of a world outline, widened."""
    s, lat = track_coordinates(terrain.track, outline_xy_m)
    return np.array([s.min() - lead_m, s.max(), lat.min() - widen_m, lat.max() + widen_m])


@dataclass(frozen=True)
class ObstacleBands:
    """Every obstacle of a course in track coordinates, widened for the car: rows (s0, s1, l0, l1)
    of station and lateral extent, s0 ``lead_m`` before the obstacle begins. Computed once per
    course and config; every plan of a drive reuses them.

    Attributes:
        bodies: Positive obstacles with a body, widened by ``half_width_m + clearance_m``.
        pits: Negative obstacles, widened by ``half_track_m + wheel_clearance_m``.
        mounds: Positive obstacles in the heightfield (drivable at a cost), widened as pits.
        lead_m: How far before its obstacle each band starts [m].
    """

    bodies: np.ndarray
    pits: np.ndarray
    mounds: np.ndarray
    lead_m: float

    @classmethod
    def of(cls, terrain: Terrain, config: TrackPlannerConfig) -> ObstacleBands:
        """The bands of ``terrain``'s obstacles for ``config``'s car and clearances."""
        body_widen = config.half_width_m + config.clearance_m
        wheel_widen = config.half_track_m + config.wheel_clearance_m

        def bands(outlines: list[np.ndarray], widen_m: float) -> np.ndarray:
            rows = [_track_band(terrain, xy, widen_m, config.lead_m) for xy in outlines]
            return np.array(rows).reshape(-1, 4)

        positives = terrain.positive_obstacles
        return cls(
            bodies=bands([o.footprint_xy_m for o in positives if not o.in_heightfield], body_widen),
            pits=bands([np.asarray(o.outline_xy_m) for o in terrain.negative_obstacles], wheel_widen),
            mounds=bands([o.footprint_xy_m for o in positives if o.in_heightfield], wheel_widen),
            lead_m=config.lead_m,
        )

    def starts_m(self) -> np.ndarray:
        """Sorted stations at which the obstacles begin [m]."""
        return np.sort(np.concatenate([self.bodies, self.pits, self.mounds])[:, 0] + self.lead_m)

    def seen(self, sight_until_m: float) -> ObstacleBands:
        """Only the obstacles that begin at or before station ``sight_until_m``."""

        def kept(bands: np.ndarray) -> np.ndarray:
            return bands[bands[:, 0] + self.lead_m <= sight_until_m]

        return ObstacleBands(kept(self.bodies), kept(self.pits), kept(self.mounds), self.lead_m)


def _add_band_penalty(
    total: np.ndarray,
    points_s: np.ndarray,
    points_lat: np.ndarray,
    obstacle_bands: np.ndarray,
    inside_cost: float,
    soft_cost: float,
    soft_margin_m: float,
) -> None:
    """Add to ``total`` (shape ...) the cost of the car's points (stations (P,) or (..., P),
    lateral offsets (..., P)) against the bands: ``inside_cost`` per point inside one, up to ``soft_cost`` per
    point within ``soft_margin_m`` of one."""
    for s0, s1, l0, l1 in obstacle_bands:
        along = (points_s >= s0) & (points_s <= s1)
        if along.any():
            outside = np.maximum(l0 - points_lat, points_lat - l1)  # < 0 inside the band
            near = np.clip(1.0 - outside / max(soft_margin_m, 1e-9), 0.0, 1.0) ** 2
            total += np.sum(along * np.where(outside <= 0.0, inside_cost, soft_cost * near), axis=-1)


def _car_points(config: TrackPlannerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Stations relative to the rear axle of the body's centre line (every 0.25 m) and of the axles."""
    body = np.arange(-config.rear_overhang_m, config.length_m - config.rear_overhang_m + 1e-9, 0.25)
    return body, np.array([0.0, config.wheelbase_m])


def blocked_moves(
    stations: np.ndarray, lateral: np.ndarray, bands: ObstacleBands, config: TrackPlannerConfig
) -> int:
    """How many moves of a path (increasing stations and lateral offsets of the rear axle, as
    :func:`planned_lateral_m` returns) put the body's centre line in a body band or an axle in a
    pit band: the hits the planner prices at 1e6 each, so 0 means the path is free of ``bands``
    (mounds, which it drives over at a cost, are not counted).

    Raises:
        ValueError: ``stations`` and ``lateral`` are not 1-D arrays of one length, or the
            stations do not increase.
    """
    stations, lateral = np.asarray(stations, dtype=np.float64), np.asarray(lateral, dtype=np.float64)
    if stations.ndim != 1 or stations.shape != lateral.shape:
        raise ValueError(
            f"stations and lateral: must be 1-D arrays of one length, got {stations.shape}, {lateral.shape}"
        )
    if np.any(np.diff(stations) <= 0):
        raise ValueError("stations: must increase")
    body, axles = _car_points(config)
    slope = np.diff(lateral) / np.diff(stations)
    hit = np.zeros(stations.size - 1)
    for points, obstacle_bands in ((body, bands.bodies), (axles, bands.pits)):
        # every move's points at once: (moves, points), placed along the move's heading
        points_s = stations[1:, None] + points
        points_lat = lateral[1:, None] + slope[:, None] * points
        _add_band_penalty(hit, points_s, points_lat, obstacle_bands, 1.0, soft_cost=0.0, soft_margin_m=1.0)
    return int(np.count_nonzero(hit))


def planned_lateral_m(
    terrain: Terrain,
    config: TrackPlannerConfig,
    start_m: tuple[float, float] = (0.0, 0.0),
    sight_until_m: float = np.inf,
    bands: ObstacleBands | None = None,
    horizon_m: float = np.inf,
    start_slope: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Stations and the planned lateral offset (+ right) of the rear axle's centre, both (M,), from
    ``start_m`` = (station, lateral offset) to the end of the track or ``horizon_m`` beyond the
    start, around the obstacles that begin at or before station ``sight_until_m`` (all by
    default).

    A lattice planner in track coordinates: dynamic programming over stations every
    ``station_step_m`` and lateral offsets every ``lateral_step_m`` within the track (less
    ``edge_margin_m``), moving at most ``max_slope`` sideways per metre. A lattice point costs
    ``centring * lateral^2`` and a move ``smoothness * change^2``. Each move also places the car
    along its heading and costs 1e6 per hit: a point of the body's centre line (every 0.25 m) in a
    positive obstacle's track band widened by ``half_width_m + clearance_m``, or an axle centre
    in a negative obstacle's band widened by ``half_track_m + wheel_clearance_m`` (a wheel in the
    pit; the body may overhang it). A course without a free path gets the least blocked one. The
    path starts at the lattice point nearest ``start_m`` (the station rounded down). ``bands``:
    ``ObstacleBands.of(terrain, config)``, passed in when one course is planned many times.

    With ``bend_steps`` > 0 each move's sideways step stays within ``bend_steps`` lateral steps of
    the one before, and the move before the first is the one nearest ``start_slope`` (the car's
    heading relative to the track, lateral metres per metre of station: :func:`track_state`).
    """
    track = terrain.track
    edge = track.width_m / 2.0 - config.edge_margin_m
    first = np.floor(np.clip(start_m[0], 0.0, track.length_m) / config.station_step_m) * config.station_step_m
    # at least one move, so a car at or past the end still has a path to pursue
    last = max(min(track.length_m, first + horizon_m), first + config.station_step_m)
    stations = np.arange(first, last + config.station_step_m, config.station_step_m)
    n_lat = int(np.floor(edge / config.lateral_step_m + 1e-9))
    laterals = np.arange(-n_lat, n_lat + 1) * config.lateral_step_m
    body, axles = _car_points(config)
    seen = (bands or ObstacleBands.of(terrain, config)).seen(sight_until_m)
    # (points along the car, their bands, the cost of a point inside one)
    checks = [(body, seen.bodies, 1e6), (axles, seen.pits, 1e6), (axles, seen.mounds, config.mound_cost)]
    start = int(np.argmin(np.abs(laterals - np.clip(start_m[1], -edge, edge))))
    if config.bend_steps > 0:
        path = _heading_lattice_path(stations, laterals, checks, start, start_slope, config)
    else:
        path = _offset_lattice_path(stations, laterals, checks, start, config)
    return stations, laterals[path]


_Check = tuple[np.ndarray, np.ndarray, float]  # points along the car, their bands, cost inside one


def _move_hits(
    station_m: float,
    moves_lat: list[np.ndarray],
    checks: list[_Check],
    shape: tuple[int, ...],
    config: TrackPlannerConfig,
) -> np.ndarray:
    """The band costs of every move ending at ``station_m``: ``moves_lat[k]`` holds the lateral
    offsets (shape + (points,)) of ``checks[k]``'s points for each move."""
    hits = np.zeros(shape)
    for (points, obstacle_bands, inside_cost), points_lat in zip(checks, moves_lat, strict=True):
        _add_band_penalty(
            hits,
            station_m + points,
            points_lat,
            obstacle_bands,
            inside_cost,
            config.soft_cost,
            config.soft_margin_m,
        )
    return hits


def _offset_lattice_path(
    stations: np.ndarray, laterals: np.ndarray, checks: list[_Check], start: int, config: TrackPlannerConfig
) -> np.ndarray:
    """Lattice indices of the cheapest path whose state is the lateral offset alone."""
    change = laterals[None, :] - laterals[:, None]  # [from, to]
    slope = change / config.station_step_m
    move = np.where(np.abs(slope) <= config.max_slope + 1e-9, config.smoothness * change**2, np.inf)
    # each check's points across the track for every move: [from, to, point]
    moves_lat = [laterals[None, :, None] + slope[:, :, None] * points for points, _, _ in checks]
    cost = np.where(np.arange(laterals.size) == start, 0.0, np.inf)
    back = np.zeros((stations.size, laterals.size), dtype=np.intp)
    for i in range(1, stations.size):
        total = cost[:, None] + move + _move_hits(stations[i], moves_lat, checks, slope.shape, config)
        back[i] = np.argmin(total, axis=0)
        cost = total[back[i], np.arange(laterals.size)] + config.centring * laterals**2
    path = np.empty(stations.size, dtype=np.intp)
    path[-1] = int(np.argmin(cost))
    for i in range(stations.size - 1, 0, -1):
        path[i - 1] = back[i, path[i]]
    return path


def _heading_lattice_path(
    stations: np.ndarray,
    laterals: np.ndarray,
    checks: list[_Check],
    start: int,
    start_slope: float,
    config: TrackPlannerConfig,
) -> np.ndarray:
    """Lattice indices of the cheapest path whose state is (lateral offset, last move), with
    bends of at most ``bend_steps`` lateral steps between moves (:func:`planned_lateral_m`)."""
    step = config.station_step_m
    n = laterals.size
    reach = int(np.floor(config.max_slope * step / config.lateral_step_m + 1e-9))
    n_moves = 2 * reach + 1  # sideways steps -reach..reach lattice points per station
    to = np.arange(n)[:, None] + np.arange(-reach, reach + 1)[None, :]  # [from, move]
    valid = (to >= 0) & (to < n)
    landing = laterals[np.clip(to, 0, n - 1)]  # [from, move]: the offset a move lands on
    change = landing - laterals[:, None]
    slope = change / step
    move_cost = np.where(valid, config.smoothness * change**2, np.inf)
    moves_lat = [landing[:, :, None] + slope[:, :, None] * points for points, _, _ in checks]
    # the last moves each move may follow: [move, k], out of range masked
    follows = np.arange(n_moves)[:, None] + np.arange(-config.bend_steps, config.bend_steps + 1)[None, :]
    in_range = (follows >= 0) & (follows < n_moves)
    follows = np.clip(follows, 0, n_moves - 1)
    origin, move = np.nonzero(valid)  # every move that stays on the lattice
    target = to[origin, move]  # valid moves only: no clipping needed
    heading = int(np.clip(np.round(start_slope * step / config.lateral_step_m), -reach, reach))
    cost = np.full((n, n_moves), np.inf)  # [lateral, last move]
    cost[start, heading + reach] = 0.0
    back_lateral = np.zeros((stations.size, n, n_moves), dtype=np.intp)
    back_move = np.zeros((stations.size, n, n_moves), dtype=np.intp)
    for i in range(1, stations.size):
        hits = _move_hits(stations[i], moves_lat, checks, slope.shape, config)
        before = np.where(in_range, cost[:, follows], np.inf)  # [from, move, k]
        pick = np.argmin(before, axis=2)  # the first of equal costs: the lowest last move
        best = np.take_along_axis(before, pick[:, :, None], axis=2)[:, :, 0]
        total = best + move_cost + hits
        new = np.full((n, n_moves), np.inf)
        new[target, move] = total[origin, move]
        back_lateral[i, target, move] = origin
        back_move[i, target, move] = follows[move, pick[origin, move]]
        cost = new + config.centring * laterals[:, None] ** 2
    path = np.empty(stations.size, dtype=np.intp)
    k, m = np.unravel_index(int(np.argmin(cost)), cost.shape)
    path[-1] = k
    for i in range(stations.size - 1, 0, -1):
        k, m = back_lateral[i, k, m], back_move[i, k, m]
        path[i - 1] = k
    return path


def track_state(track: Track, pose: np.ndarray) -> tuple[float, float, float]:
    """The car's station and lateral offset (+ right) [m] on ``track`` and its heading relative to
    the track as the lateral change per metre of station (the ``start_slope`` of
    :func:`planned_lateral_m`), from ``pose`` (x, y, z, roll, pitch, yaw of the rear axle).

    Raises:
        ValueError: ``pose`` is not 6 finite numbers.
    """
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape != (6,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"pose: must be 6 finite numbers (x, y, z, roll, pitch, yaw), got {pose.tolist()}")
    ahead = vehicle_to_world_xy(np.array([[0.0, 0.0], [0.0, 1.0]]), pose[:2], float(pose[5]))
    s, lat = track_coordinates(track, ahead)
    return float(s[0]), float(lat[0]), float((lat[1] - lat[0]) / max(s[1] - s[0], 1e-3))


class TrackPlannerDriver:
    """Pure pursuit along :func:`planned_lateral_m`'s path for ``terrain`` (reads ground truth).

    Once the rear axle is more than ``replan_deviation_m`` off the path (a noisy or a learner's
    drive, DAgger), it plans again from where the car is: following the old path from the wrong
    side of a pit would steer back across the pit. With ``sight_m`` > 0 it also plans again from
    where the car is whenever an obstacle comes within ``sight_m`` ahead, and ignores those beyond.
    """

    def __init__(self, terrain: Terrain, config: TrackPlannerConfig | None = None) -> None:
        self.config = config or TrackPlannerConfig()
        self.terrain = terrain
        self.replans = 0
        self._bands = ObstacleBands.of(terrain, self.config)
        self._starts_m = self._bands.starts_m() if self.config.sight_m > 0 else np.empty(0)
        self._horizon_m = self.config.plan_horizon_m or np.inf
        self._initial = planned_lateral_m(
            terrain, self.config, (0.0, 0.0), self._sight_until(0.0), self._bands, self._horizon_m
        )
        self._sighted = self._in_sight(0.0)
        self._follow(*self._initial)

    @property
    def path_m(self) -> tuple[np.ndarray, np.ndarray]:
        """The path it follows now: stations and lateral offsets of the rear axle [m]."""
        return self._stations, self._lateral

    def _sight_until(self, station_m: float) -> float:
        return station_m + self.config.sight_m if self.config.sight_m > 0 else np.inf

    def _in_sight(self, station_m: float) -> int:
        return int(np.searchsorted(self._starts_m, self._sight_until(station_m), side="right"))

    def _follow(self, stations: np.ndarray, lateral: np.ndarray) -> None:
        self._stations, self._lateral = stations, lateral
        self.route_xy_m, _ = self.terrain.track.pose_at(stations, lateral)
        self._pursuit = PurePursuitDriver(self.route_xy_m, self.config.pursuit)

    def reset(self, seed: int | None = None) -> None:
        """Restart at the beginning of the first path."""
        self.replans = 0
        self._sighted = self._in_sight(0.0)
        self._follow(*self._initial)

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """Pure pursuit's ``[longitudinal, steering]`` towards the planned path (planned again
        from the car's position at every step with ``plan_horizon_m``, else when it is off the
        path or a new obstacle is in sight)."""
        config = self.config
        replanning = config.replan_deviation_m > 0 or config.sight_m > 0 or config.plan_horizon_m > 0
        if replanning and "pose" in info:
            pose = np.asarray(info["pose"], dtype=np.float64)
            if pose.shape == (6,) and np.all(np.isfinite(pose)):
                station, lateral, slope = track_state(self.terrain.track, pose)
                sighted = self._in_sight(station)
                off_path = abs(lateral - float(np.interp(station, self._stations, self._lateral)))
                deviation = config.replan_deviation_m
                if (
                    config.plan_horizon_m > 0
                    or sighted > self._sighted
                    or (deviation > 0 and off_path > deviation)
                ):
                    start, until = (station, lateral), self._sight_until(station)
                    path = planned_lateral_m(
                        self.terrain, config, start, until, self._bands, self._horizon_m, slope
                    )
                    self._follow(*path)
                    self._sighted = max(sighted, self._sighted)
                    self.replans += 1
        return self._pursuit.act(obs, info)
