"""Scenario presets: ready-made terrains for braking tests, navigation and paper T's scenes.

Every preset starts the vehicle at the origin facing world +Y (``start_xy_yaw = (0, 0, 0)``) on the
track centre line and puts the goal ``goal_margin_m`` before the end of the track. Distances
"ahead" are measured along the track from the start pose (the vehicle frame origin, see
``negobs_gym/core/pose.py``). Every preset has one signature shape: its scene parameters first
(positional or keyword), then the common keyword-only parameters in one order — ``seed``
(roughness noise and, for the winding course, the layout), ``rough`` where the preset has it,
``length_m`` where it is not a scene parameter, and ``resolution_m``. ``PRESETS`` maps a name to
each preset function; scenario specs (:mod:`negobs_gym.spec`) call them by name.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from negobs_gym.errors import require
from negobs_gym.sim.carving import (
    DEPTH_RANGE_M,
    NegativeObstacleSpec,
    PositiveObstacleSpec,
    sample_pit_spec,
)
from negobs_gym.sim.terrain import (
    BendSpec,
    BorderConfig,
    RoughnessConfig,
    TerrainConfig,
    generate_terrain,
)
from negobs_gym.sim.types import Terrain

# Room left on the track beyond the last obstacle of a straight preset [m].
_RUN_OUT_AFTER_OBSTACLE_M = 30.0
# Tightest bend of the winding course [m]; must stay >= half the 30 m corridor.
_MIN_BEND_RADIUS_M = 18.0


def _roughness(rough: bool) -> RoughnessConfig:
    return RoughnessConfig() if rough else RoughnessConfig.flat()


def braking_track(
    ditch_distance_m: float = 30.0,
    ditch_length_m: float = 1.0,
    ditch_width_m: float = 3.0,
    ditch_depth_m: float = 0.8,
    lateral_offset_m: float = 0.0,
    wall_slope_deg: float = 90.0,
    *,
    seed: int = 0,
    rough: bool = True,
    length_m: float | None = None,
    resolution_m: float = 0.10,
) -> Terrain:
    """Straight track along +Y with one ditch (obstacle id ``"ditch-0"``).

    The ditch's near edge is ``ditch_distance_m`` ahead of the start; ``ditch_length_m`` is along
    the track, ``ditch_width_m`` across it, its centre ``lateral_offset_m`` to the right of the
    centre line. ``rough=False`` gives flat ground around the ditch.
    """
    require(ditch_distance_m > 0, "ditch_distance_m", f"must be > 0, got {ditch_distance_m!r}")
    total = ditch_distance_m + ditch_length_m + _RUN_OUT_AFTER_OBSTACLE_M
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=length_m if length_m is not None else total,
        roughness=_roughness(rough),
        negative_obstacles=(
            NegativeObstacleSpec(
                kind="ditch",
                length_m=ditch_length_m,
                width_m=ditch_width_m,
                depth_m=ditch_depth_m,
                wall_slope_deg=wall_slope_deg,
                station_m=ditch_distance_m + 0.5 * ditch_length_m,
                lateral_m=lateral_offset_m,
            ),
        ),
    )
    return generate_terrain(config, seed)


def trench_crossing(
    trench_distance_m: float = 30.0,
    trench_length_m: float = 3.0,
    trench_depth_m: float = 1.0,
    *,
    seed: int = 0,
    rough: bool = True,
    resolution_m: float = 0.10,
) -> Terrain:
    """Straight track with a trench across its full width (id ``"trench-0"``).

    A ~3 m long trench (along the track) traps a full-size vehicle (issue 2). It spans the track
    and both verges so the vehicle cannot pass beside it.
    """
    require(trench_distance_m > 0, "trench_distance_m", f"must be > 0, got {trench_distance_m!r}")
    track_width_m = 6.0
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=trench_distance_m + trench_length_m + _RUN_OUT_AFTER_OBSTACLE_M,
        track_width_m=track_width_m,
        roughness=_roughness(rough),
        negative_obstacles=(
            NegativeObstacleSpec(
                kind="trench",
                length_m=trench_length_m,
                width_m=track_width_m + 4.0,
                depth_m=trench_depth_m,
                station_m=trench_distance_m + 0.5 * trench_length_m,
            ),
        ),
    )
    return generate_terrain(config, seed)


def rough_track(length_m: float = 200.0, *, seed: int = 0, resolution_m: float = 0.10) -> Terrain:
    """Straight rough track with verges and no obstacles at all (false-alarm tests)."""
    config = TerrainConfig(resolution_m=resolution_m, length_m=length_m)
    return generate_terrain(config, seed)


def straight_banked_track(length_m: float = 80.0, *, seed: int = 0, resolution_m: float = 0.10) -> Terrain:
    """Paper T's straight track between two earth banks."""
    bank = BorderConfig(kind="bank")
    config = TerrainConfig(resolution_m=resolution_m, length_m=length_m, left_border=bank, right_border=bank)
    return generate_terrain(config, seed)


def bend(
    angle_deg: float = 60.0,
    radius_m: float = 30.0,
    *,
    seed: int = 0,
    resolution_m: float = 0.10,
) -> Terrain:
    """Paper T's bend: 20 m straight, a circular bend (+ = left), 30 m straight, banked sides."""
    require(radius_m > 0, "radius_m", f"must be > 0, got {radius_m!r}")
    arc = radius_m * np.radians(abs(angle_deg))
    bank = BorderConfig(kind="bank")
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=20.0 + arc + 30.0,
        bends=(BendSpec(start_m=20.0, length_m=arc, angle_deg=angle_deg),),
        left_border=bank,
        right_border=bank,
    )
    return generate_terrain(config, seed)


def oncoming_car(car_distance_m: float = 35.0, *, seed: int = 0, resolution_m: float = 0.10) -> Terrain:
    """Paper T's scene: a car (as a static box) facing us in the left half of the track."""
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=car_distance_m + _RUN_OUT_AFTER_OBSTACLE_M,
        positive_obstacles=(
            PositiveObstacleSpec(kind="vehicle", station_m=car_distance_m, lateral_m=-1.5, yaw_deg=180.0),
        ),
    )
    return generate_terrain(config, seed)


def parked_motorbike(bike_distance_m: float = 25.0, *, seed: int = 0, resolution_m: float = 0.10) -> Terrain:
    """Paper T's scene: a motorbike parked at the right edge of the track."""
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=bike_distance_m + _RUN_OUT_AFTER_OBSTACLE_M,
        positive_obstacles=(
            PositiveObstacleSpec(kind="motorbike", station_m=bike_distance_m, lateral_m=2.5),
        ),
    )
    return generate_terrain(config, seed)


def pedestrian_near_dropoff(
    pedestrian_distance_m: float = 25.0, *, seed: int = 0, resolution_m: float = 0.10
) -> Terrain:
    """Paper T's scene: a pedestrian on the right verge, just before a drop-off."""
    right = BorderConfig(kind="dropoff")
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=pedestrian_distance_m + _RUN_OUT_AFTER_OBSTACLE_M,
        right_border=right,
        positive_obstacles=(
            PositiveObstacleSpec(
                kind="pedestrian",
                station_m=pedestrian_distance_m,
                lateral_m=0.5 * 6.0 + 0.5 * right.verge_width_m,
            ),
        ),
    )
    return generate_terrain(config, seed)


def winding_course(
    length_m: float = 200.0,
    *,
    n_negative: int = 6,
    n_positive: int = 4,
    seed: int = 0,
    resolution_m: float = 0.10,
) -> Terrain:
    """Winding track with mixed obstacles placed from ``seed``; the goal is near its end.

    Bends alternate left and right, swinging the heading 20-40 deg either side of +Y. Pits of
    paper N's sizes +-20 %, 1-2 m long ditches, craters, rocks, boxes and mounds are spread along
    the track from 20 m on, at random lateral offsets within 2 m of the centre line.
    """
    require(length_m >= 60.0, "length_m", f"must be >= 60 m for a winding course, got {length_m!r}")
    require(n_negative >= 0, "n_negative", "must be >= 0")
    require(n_positive >= 0, "n_positive", "must be >= 0")
    layout = np.random.default_rng([int(seed), 1])  # separate stream from the terrain noise
    bends = []
    s, sign, heading_deg = 20.0, 1.0, 0.0
    while True:
        # Swing the heading to alternately +-20..40 deg off +Y so the course zig-zags forward
        # instead of drifting sideways (a narrower heightfield for the physics world).
        target = sign * float(layout.uniform(20.0, 40.0))
        angle = target - heading_deg
        arc = max(float(layout.uniform(20.0, 30.0)), np.radians(abs(angle)) * _MIN_BEND_RADIUS_M)
        if s + arc > length_m - 20.0:
            break
        bends.append(BendSpec(start_m=s, length_m=arc, angle_deg=angle))
        s += arc + float(layout.uniform(10.0, 25.0))
        heading_deg, sign = target, -sign
    n_total = n_negative + n_positive
    stations = np.linspace(20.0, length_m - 15.0, n_total + 2)[1:-1] if n_total else []
    negatives, positives = [], []
    for k, station in enumerate(stations):
        lateral = float(layout.uniform(-2.0, 2.0))
        if (k % 2 == 0 and len(negatives) < n_negative) or len(positives) >= n_positive:
            pick = int(layout.integers(0, 3))
            if pick == 0:
                spec = sample_pit_spec(layout, station_m=float(station), lateral_m=lateral)
            else:
                length = float(layout.uniform(1.0, 2.0))
                width = 3.0 if pick == 1 else length
                spec = NegativeObstacleSpec(
                    kind="ditch" if pick == 1 else "crater",
                    length_m=length,
                    width_m=width,
                    depth_m=float(layout.uniform(*DEPTH_RANGE_M)),
                    station_m=float(station),
                    lateral_m=lateral,
                )
            negatives.append(spec)
        else:
            kind = ("rock", "box", "mound")[int(layout.integers(0, 3))]
            positives.append(PositiveObstacleSpec(kind=kind, station_m=float(station), lateral_m=lateral))
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=length_m,
        bends=tuple(bends),
        left_border=BorderConfig(kind="bank"),
        right_border=BorderConfig(kind="verge"),
        negative_obstacles=tuple(negatives),
        positive_obstacles=tuple(positives),
    )
    return generate_terrain(config, seed)


CLUTTER_KINDS: tuple[str, ...] = ("walls", "vehicles", "rocks", "vegetation")
_TRACK_HALF_M = 3.0  # half of TerrainConfig's default 6 m track
_CLEAR_HALF_M = 1.6  # clutter on the track keeps this far from the centre line (vehicle 1.8 m wide)


def _clutter_specs(kind: str, layout: np.random.Generator, start_m: float, end_m: float) -> list:
    """Positive obstacles of one clutter kind between stations ``start_m`` and ``end_m``."""
    specs: list[PositiveObstacleSpec] = []

    def side() -> float:
        return float(layout.choice((-1.0, 1.0)))

    if kind == "walls":  # wall segments beyond the verge, alternating sides
        s, sign = start_m, 1.0
        while s < end_m - 4.0:
            length = float(layout.uniform(6.0, 14.0))
            specs.append(
                PositiveObstacleSpec(
                    kind="box",
                    station_m=s + 0.5 * length,
                    lateral_m=sign * float(layout.uniform(_TRACK_HALF_M + 1.0, _TRACK_HALF_M + 2.5)),
                    size_m=(length, 0.3, float(layout.uniform(1.2, 2.5))),
                )
            )
            s += length + float(layout.uniform(4.0, 12.0))
            sign = -sign
    elif kind == "vehicles":  # parked cars on the track edge and the verge
        for station in np.arange(start_m, end_m, 18.0) + layout.uniform(0.0, 6.0):
            specs.append(
                PositiveObstacleSpec(
                    kind="vehicle",
                    station_m=float(station),
                    lateral_m=side() * float(layout.uniform(_CLEAR_HALF_M + 1.0, _TRACK_HALF_M + 2.0)),
                    yaw_deg=float(layout.uniform(-8.0, 8.0)) + float(layout.choice((0.0, 180.0))),
                )
            )
    elif kind == "rocks":  # rock fields: groups of rocks on and beside the track
        for centre in np.arange(start_m, end_m, 15.0) + layout.uniform(0.0, 5.0):
            sign = side()
            for _ in range(int(layout.integers(5, 11))):
                size = float(layout.uniform(0.3, 0.9))
                specs.append(
                    PositiveObstacleSpec(
                        kind="rock",
                        station_m=float(centre + layout.uniform(-3.0, 3.0)),
                        lateral_m=sign * float(layout.uniform(_CLEAR_HALF_M + 0.5 * size, 7.0)),
                        yaw_deg=float(layout.uniform(0.0, 180.0)),
                        size_m=(
                            size,
                            size * float(layout.uniform(0.6, 1.0)),
                            size * float(layout.uniform(0.5, 0.8)),
                        ),
                    )
                )
    elif kind == "vegetation":  # stems and shrubs, about one per metre of track
        for station in np.arange(start_m, end_m, 1.0) + layout.uniform(
            0.0, 1.0, size=int(np.ceil(end_m - start_m))
        ):
            lateral = side() * float(layout.uniform(_CLEAR_HALF_M + 0.3, 9.0))
            if layout.random() < 0.7:
                d = float(layout.uniform(0.04, 0.2))
                spec = PositiveObstacleSpec(
                    kind="pole",
                    station_m=float(station),
                    lateral_m=lateral,
                    size_m=(d, d, float(layout.uniform(0.8, 2.5))),
                )
            else:
                w = float(layout.uniform(0.3, 0.7))
                spec = PositiveObstacleSpec(
                    kind="box",
                    station_m=float(station),
                    lateral_m=lateral,
                    yaw_deg=float(layout.uniform(0.0, 90.0)),
                    size_m=(w, w, float(layout.uniform(0.4, 1.0))),
                )
            specs.append(spec)
    return specs


def clutter_track(
    *,
    seed: int = 0,
    clutter: tuple[str, ...] = CLUTTER_KINDS,
    pits: bool = False,
    length_m: float = 140.0,
    resolution_m: float = 0.10,
) -> Terrain:
    """Straight rough track through clutter that real vehicles meet (false-alarm tests, issue 10).

    ``clutter`` picks from :data:`CLUTTER_KINDS`: ``"walls"`` (6-14 m wall segments, 1.2-2.5 m
    high, beyond the verges; the left border is an earth embankment whenever walls are asked for),
    ``"vehicles"`` (parked cars every ~18 m on the track edge or the verge), ``"rocks"`` (fields of
    5-10 rocks, 0.3-0.9 m, every ~15 m, on the track's edge and beside it) and ``"vegetation"``
    (about one thin stem (pole, 4-20 cm) or shrub (box) per metre, both sides). Clutter on the
    track keeps ``1.6 m`` from the centre line so the vehicle can drive it straight. ``pits=True``
    adds a paper N pit (sizes +-20 %, 0.3-1.5 m deep) on the centre line every 30 m from 25 m on
    (ids ``"pit-<k>"``). The layout comes from ``seed`` (a stream separate from the roughness).
    """
    require(length_m >= 40.0, "length_m", f"must be >= 40 m, got {length_m!r}")
    unknown = set(clutter) - set(CLUTTER_KINDS)
    require(not unknown, "clutter", f"unknown clutter kinds {sorted(unknown)}; expected {CLUTTER_KINDS}")
    layout = np.random.default_rng([int(seed), 2])
    positives = []
    for kind in CLUTTER_KINDS:
        if kind in clutter:
            positives.extend(_clutter_specs(kind, layout, 8.0, length_m - 10.0))
    negatives = ()
    if pits:
        negatives = tuple(
            sample_pit_spec(layout, station_m=float(station))
            for station in np.arange(25.0, length_m - 10.0, 30.0)
        )
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=length_m,
        left_border=BorderConfig(kind="bank") if "walls" in clutter else BorderConfig(),
        negative_obstacles=negatives,
        positive_obstacles=tuple(positives),
    )
    return generate_terrain(config, seed)


PRESETS: dict[str, Callable[..., Terrain]] = {
    "braking_track": braking_track,
    "trench_crossing": trench_crossing,
    "rough_track": rough_track,
    "straight_banked_track": straight_banked_track,
    "bend": bend,
    "oncoming_car": oncoming_car,
    "parked_motorbike": parked_motorbike,
    "pedestrian_near_dropoff": pedestrian_near_dropoff,
    "winding_course": winding_course,
    "clutter_track": clutter_track,
}
