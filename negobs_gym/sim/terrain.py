"""Procedural off-road terrain: a corridor of heightfield around a drivable track (docs/terrain.md).

The heightfield is the sum of

* gentle slopes (long-wavelength value noise),
* bumps and fine roughness (shorter wavelengths), full strength off the track and scaled down by
  ``track_scale`` on the driven track so a 2000 kg car at 25 km/h can drive it,
* two ruts along the track,
* the border profile of each side: a flat grass verge, then an earth bank or a drop-off,
* the course's longitudinal profile: crests and dips, raised cosines in station across the whole
  corridor (:class:`ProfileFeature`),

then negative obstacles are carved in and positive ones placed (:mod:`negobs_gym.sim.carving`).
Every noise octave is peak-normalised, so an amplitude in the config is the largest height that
octave contributes anywhere on the grid. All randomness comes from ``np.random.default_rng(seed)``
drawn in a fixed order (slopes, bumps, fine, then the profile's ranges), so the same seed gives
the same arrays bit for bit.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from negobs_gym.core import libm
from negobs_gym.errors import ConfigError, GeometryError, require
from negobs_gym.sim.carving import (
    NegativeObstacleSpec,
    PositiveObstacleSpec,
    carve_negative_obstacle,
    place_positive_obstacle,
)
from negobs_gym.sim.spline import cubic_spline_grid
from negobs_gym.sim.types import HeightField, Terrain, Track

logger = logging.getLogger(__name__)

BorderKind = Literal["verge", "bank", "dropoff"]
BORDER_KINDS: tuple[str, ...] = get_args(BorderKind)
ProfileKind = Literal["crest", "dip"]
PROFILE_KINDS: tuple[str, ...] = get_args(ProfileKind)
#: A profile number: a value, or a range ``(low, high)`` drawn from the terrain's generator.
Spread = float | tuple[float, float]
_LATERAL_LATTICE_M = 0.5  # lattice of the interpolated lateral-offset field [m]
_PROFILE_TABLE_M = 0.01  # sample spacing of a profile feature's cosine table [m]


def _finite(value: float) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def _require_nonneg(obj: object, names: tuple[str, ...]) -> None:
    for name in names:
        value = getattr(obj, name)
        require(_finite(value) and value >= 0, name, f"must be finite and >= 0, got {value!r}")


def _require_pos(obj: object, names: tuple[str, ...]) -> None:
    for name in names:
        value = getattr(obj, name)
        require(_finite(value) and value > 0, name, f"must be finite and > 0, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class BendSpec:
    """A circular bend of the centre line: heading changes by ``angle_deg`` over ``length_m``."""

    start_m: float  # station where the bend begins [m]
    length_m: float  # arc length of the bend [m]
    angle_deg: float  # heading change [deg]; + = to the left (counter-clockwise)

    def __post_init__(self) -> None:
        _require_nonneg(self, ("start_m",))
        _require_pos(self, ("length_m",))
        require(
            _finite(self.angle_deg) and abs(self.angle_deg) <= 180,
            "angle_deg",
            f"must be finite with |angle| <= 180, got {self.angle_deg!r}",
        )

    @property
    def radius_m(self) -> float:
        """Radius of the bend [m] (inf for a zero angle)."""
        ang = abs(math.radians(self.angle_deg))
        return math.inf if ang == 0 else self.length_m / ang


def _ends(value: Spread) -> tuple[float, float]:
    """(low, high) of a profile number (both the value when it is no range)."""
    if isinstance(value, tuple):
        return value
    return value, value


@dataclass(frozen=True, kw_only=True)
class ProfileFeature:
    """A crest or a dip of the course's longitudinal profile (docs/safety.md, "Blind crests").

    The ground rises (crest) or sinks (dip) by a raised cosine in station,
    ``height * (1 + cos(2 pi (s - station) / length)) / 2`` for ``|s - station| <= length / 2``,
    across the whole corridor (track, verges and borders), so physics and every LiDAR see it and
    obstacles on it sit on the displaced ground. Each number may be a range ``(low, high)``, drawn
    per terrain from its seed (:meth:`drawn`).
    """

    kind: str = "crest"  # one of PROFILE_KINDS
    station_m: Spread  # station of the top (crest) or the bottom (dip), from the start [m]
    height_m: Spread = 2.0  # rise of a crest or depth of a dip [m], > 0
    length_m: Spread = 24.0  # foot to foot along the track [m], > 0; steepest slope pi*h/length

    _NUMBERS = ("station_m", "height_m", "length_m")

    def __post_init__(self) -> None:
        require(
            self.kind in PROFILE_KINDS,
            "kind",
            f"unknown profile kind {self.kind!r}; expected one of {PROFILE_KINDS}",
        )
        for name in self._NUMBERS:
            value = getattr(self, name)
            if isinstance(value, list):
                value = tuple(value)
                object.__setattr__(self, name, value)
            ok = (_finite(value) and not isinstance(value, bool)) or (
                isinstance(value, tuple)
                and len(value) == 2
                and all(_finite(v) and not isinstance(v, bool) for v in value)
                and value[0] <= value[1]
            )
            require(ok, name, f"must be a finite number or a range [low, high], low <= high; got {value!r}")
        _require_nonneg_ends(self, ("station_m",))
        for name in ("height_m", "length_m"):
            low, _ = _ends(getattr(self, name))
            require(low > 0, name, f"must be > 0, got {getattr(self, name)!r}")

    def drawn(self, rng: np.random.Generator) -> ProfileFeature:
        """This feature with its ranges drawn from ``rng`` (one uniform draw per range, in the
        order station, height, length; fixed numbers draw nothing)."""
        values = {}
        for name in self._NUMBERS:
            value = getattr(self, name)
            values[name] = float(rng.uniform(*value)) if isinstance(value, tuple) else float(value)
        return ProfileFeature(kind=self.kind, **values)

    def offset_m(self, station_m: np.ndarray) -> np.ndarray:
        """Height offset [m] at stations ``station_m`` (a drawn feature: no ranges)."""
        s0, h, length = (float(_ends(getattr(self, n))[0]) for n in self._NUMBERS)
        # the cosine tabulated with the C library's (math.cos, CPU-independent) every
        # _PROFILE_TABLE_M and interpolated linearly: under a micrometre off for any sane length
        n = max(2, math.ceil(length / _PROFILE_TABLE_M) + 1)
        u = np.linspace(-0.5, 0.5, n)
        table = np.array([0.5 * (1.0 + math.cos(2.0 * math.pi * v)) for v in u.tolist()])
        rel = (np.asarray(station_m, dtype=np.float64) - s0) / length
        bump = np.interp(rel, u, table, left=0.0, right=0.0)
        return (h if self.kind == "crest" else -h) * bump


def _require_nonneg_ends(obj: object, names: tuple[str, ...]) -> None:
    for name in names:
        low, _ = _ends(getattr(obj, name))
        require(low >= 0, name, f"must be >= 0, got {getattr(obj, name)!r}")


@dataclass(frozen=True, kw_only=True)
class RoughnessConfig:
    """Off-road roughness; every amplitude is the peak height of its octave [m]."""

    slope_amplitude_m: float = 1.0  # gentle slopes over the whole corridor (docs/terrain.md)
    slope_wavelength_m: float = 60.0  # feature size of the slopes [m]
    bump_amplitude_m: float = 0.25  # off-track bumps; docs/terrain.md bumps 5-30 cm
    bump_wavelength_m: float = 3.0
    fine_amplitude_m: float = 0.05  # fine clods/grass tufts
    fine_wavelength_m: float = 0.6
    track_scale: float = 0.15  # share of bumps + fine roughness left on the driven track
    track_blend_m: float = 1.0  # distance beyond the track edge over which roughness ramps up
    rut_depth_m: float = 0.05  # depth of the two wheel ruts along the track
    rut_spacing_m: float = 1.7  # distance between the rut centres (a car's wheel track) [m]
    rut_width_m: float = 0.4  # full width of a rut at half depth [m]

    def __post_init__(self) -> None:
        _require_nonneg(self, ("slope_amplitude_m", "bump_amplitude_m", "fine_amplitude_m", "rut_depth_m"))
        _require_pos(
            self,
            (
                "slope_wavelength_m",
                "bump_wavelength_m",
                "fine_wavelength_m",
                "track_blend_m",
                "rut_spacing_m",
                "rut_width_m",
            ),
        )
        require(
            _finite(self.track_scale) and 0 <= self.track_scale <= 1,
            "track_scale",
            f"must be in [0, 1], got {self.track_scale!r}",
        )

    @classmethod
    def flat(cls) -> RoughnessConfig:
        """No slopes, bumps or ruts: flat ground."""
        return cls(slope_amplitude_m=0.0, bump_amplitude_m=0.0, fine_amplitude_m=0.0, rut_depth_m=0.0)


@dataclass(frozen=True, kw_only=True)
class BorderConfig:
    """One side of the track beyond its edge: verge, then an earth bank or a drop-off (paper T)."""

    kind: str = "verge"  # one of BORDER_KINDS
    verge_width_m: float = 1.5  # flat grass strip between the track edge and a bank/drop-off
    bank_height_m: float = 0.8  # height of an earth bank above the verge [m]
    bank_width_m: float = 2.0  # horizontal run of the bank's slope [m]
    dropoff_depth_m: float = 1.5  # drop of a drop-off below the verge [m]
    dropoff_width_m: float = 0.5  # horizontal run of the drop-off face [m]

    def __post_init__(self) -> None:
        require(
            self.kind in BORDER_KINDS,
            "kind",
            f"unknown border kind {self.kind!r}; expected one of {BORDER_KINDS}",
        )
        _require_nonneg(self, ("verge_width_m", "bank_height_m", "dropoff_depth_m"))
        _require_pos(self, ("bank_width_m", "dropoff_width_m"))

    def profile_m(self, beyond_edge_m: np.ndarray) -> np.ndarray:
        """Height offset [m] at a distance beyond the track edge (<= 0 means on the track)."""
        if self.kind == "verge":
            return np.zeros_like(beyond_edge_m)
        run = self.bank_width_m if self.kind == "bank" else self.dropoff_width_m
        t = np.clip((beyond_edge_m - self.verge_width_m) / run, 0.0, 1.0)
        step = t * t * (3.0 - 2.0 * t)
        return step * (self.bank_height_m if self.kind == "bank" else -self.dropoff_depth_m)


@dataclass(frozen=True, kw_only=True)
class TerrainConfig:
    """A course: track geometry, roughness, borders and obstacles. Lengths in m, angles in deg."""

    resolution_m: float = 0.10  # heightfield sample spacing; docs/terrain.md: 5-10 cm
    length_m: float = 200.0  # centre-line length from the start [m]
    lead_in_m: float = 10.0  # terrain behind the start [m]
    run_out_m: float = 10.0  # terrain beyond the end of the centre line [m]
    corridor_width_m: float = 30.0  # width of terrain around the centre line [m]
    track_width_m: float = 6.0  # drivable track width [m]
    start_xy_m: tuple[float, float] = (0.0, 0.0)
    start_yaw_deg: float = 0.0  # 0 = the track starts along world +Y
    bends: tuple[BendSpec, ...] = ()
    roughness: RoughnessConfig = field(default_factory=RoughnessConfig)
    left_border: BorderConfig = field(default_factory=BorderConfig)
    right_border: BorderConfig = field(default_factory=BorderConfig)
    negative_obstacles: tuple[NegativeObstacleSpec, ...] = ()
    positive_obstacles: tuple[PositiveObstacleSpec, ...] = ()
    profile: tuple[ProfileFeature, ...] = ()  # crests and dips along the track
    goal_margin_m: float = 5.0  # the goal lies this far before the end of the centre line [m]

    def __post_init__(self) -> None:
        require(
            _finite(self.resolution_m) and 0 < self.resolution_m <= 1.0,
            "resolution_m",
            f"must be in (0, 1] m, got {self.resolution_m!r}",
        )
        _require_pos(self, ("length_m", "corridor_width_m", "track_width_m"))
        _require_nonneg(self, ("lead_in_m", "run_out_m", "goal_margin_m"))
        require(
            self.corridor_width_m >= self.track_width_m + 2 * self.resolution_m,
            "corridor_width_m",
            f"must exceed track_width_m ({self.track_width_m}) by two samples",
        )
        require(self.goal_margin_m < self.length_m, "goal_margin_m", "must be < length_m")
        require(
            len(self.start_xy_m) == 2 and all(_finite(v) for v in self.start_xy_m),
            "start_xy_m",
            f"must be two finite numbers, got {self.start_xy_m!r}",
        )
        require(_finite(self.start_yaw_deg), "start_yaw_deg", "must be finite")
        for name, typ in (
            ("roughness", RoughnessConfig),
            ("left_border", BorderConfig),
            ("right_border", BorderConfig),
        ):
            require(isinstance(getattr(self, name), typ), name, f"must be a {typ.__name__}")
        for name, typ in (
            ("bends", BendSpec),
            ("negative_obstacles", NegativeObstacleSpec),
            ("positive_obstacles", PositiveObstacleSpec),
            ("profile", ProfileFeature),
        ):
            items = getattr(self, name)
            require(isinstance(items, tuple), name, "must be a tuple")
            for k, item in enumerate(items):
                require(isinstance(item, typ), f"{name}[{k}]", f"must be a {typ.__name__}")
        prev_end = 0.0
        for k, bend in enumerate(self.bends):
            require(
                bend.start_m >= prev_end,
                f"bends[{k}].start_m",
                "bends must be in order and must not overlap",
            )
            require(
                bend.start_m + bend.length_m <= self.length_m,
                f"bends[{k}].length_m",
                "the bend runs past length_m",
            )
            require(
                bend.radius_m >= 0.5 * self.corridor_width_m,
                f"bends[{k}].length_m",
                f"radius {bend.radius_m:.1f} m is below half the corridor width "
                f"({0.5 * self.corridor_width_m} m); lengthen the bend or reduce its angle",
            )
            prev_end = bend.start_m + bend.length_m
        for k, feature in enumerate(self.profile):
            _, high = _ends(feature.station_m)
            require(
                high <= self.length_m,
                f"profile[{k}].station_m",
                f"must lie on the course, within [0, length_m = {self.length_m}], got {feature.station_m!r}",
            )


def build_centreline(config: TerrainConfig) -> np.ndarray:
    """Centre line (N, 2) from the start, sampled every ``resolution_m`` along its length."""
    step = config.resolution_m
    n = math.ceil(config.length_m / step)
    ds = config.length_m / n
    s0 = np.arange(n) * ds
    turn = np.zeros(n)  # heading change within each segment [rad]
    for bend in config.bends:
        overlap = np.clip(
            np.minimum(s0 + ds, bend.start_m + bend.length_m) - np.maximum(s0, bend.start_m),
            0.0,
            None,
        )
        turn += math.radians(bend.angle_deg) * overlap / bend.length_m
    yaw0 = math.radians(config.start_yaw_deg)
    # Exact integral of the piecewise-constant curvature; each chord takes the mean heading.
    yaw_end = yaw0 + np.concatenate([[0.0], np.cumsum(turn)])
    yaw_mid = 0.5 * (yaw_end[:-1] + yaw_end[1:])
    d = ds * np.stack([-np.sin(yaw_mid), np.cos(yaw_mid)], axis=1)
    start = np.asarray(config.start_xy_m, dtype=np.float64)
    return np.vstack([start, start + np.cumsum(d, axis=0)])


def track_coordinates(
    track: Track, xy_m: np.ndarray, *, spacing_m: float = 0.1, extend_m: float = 50.0
) -> tuple[np.ndarray, np.ndarray]:
    """Station and lateral offset (+ right) [m] of world points (..., 2) relative to ``track``.

    Uses the nearest point of the centre line resampled at ``spacing_m`` and extended straight by
    ``extend_m`` beyond both ends, so points behind the start get negative stations.
    """
    xy = np.asarray(xy_m, dtype=np.float64)
    if xy.shape[-1:] != (2,) or not np.all(np.isfinite(xy)):
        raise GeometryError(f"xy_m must be finite points of shape (..., 2), got shape {xy.shape}")
    s = np.arange(-extend_m, track.length_m + extend_m + spacing_m, spacing_m)
    pts, yaw = track.pose_at(s)
    tree = cKDTree(pts)
    _, k = tree.query(xy.reshape(-1, 2))
    fwd = np.stack([-np.sin(yaw[k]), np.cos(yaw[k])], axis=1)
    rel = xy.reshape(-1, 2) - pts[k]
    station = s[k] + np.sum(rel * fwd, axis=1)
    lateral = rel[:, 0] * fwd[:, 1] - rel[:, 1] * fwd[:, 0]  # dot with right = (fy, -fx)
    return station.reshape(xy.shape[:-1]), lateral.reshape(xy.shape[:-1])


def value_noise(
    rng: np.random.Generator, shape: tuple[int, int], resolution_m: float, wavelength_m: float
) -> np.ndarray:
    """Smooth noise of feature size ``wavelength_m``, peak-normalised to max |value| = 1.

    Gaussian lattice values every half wavelength, cubic-spline interpolated to the grid
    (scipy's ``map_coordinates(order=3, mode="nearest")`` bit for bit, :mod:`~negobs_gym.sim.spline`).
    """
    ny, nx = shape
    cell = max(0.5 * wavelength_m / resolution_m, 1.0)  # lattice spacing in samples
    lat_shape = (math.ceil((ny - 1) / cell) + 4, math.ceil((nx - 1) / cell) + 4)
    lattice = rng.standard_normal(lat_shape)
    out = cubic_spline_grid(lattice, np.arange(ny) / cell + 1.0, np.arange(nx) / cell + 1.0)
    peak = float(np.max(np.abs(out)))
    return out / peak if peak > 0 else out


def _grid(config: TerrainConfig, centreline: np.ndarray) -> tuple[tuple[float, float], int, int]:
    """Origin and size of a grid covering the corridor around the extended centre line."""
    track = Track(centreline_xy_m=centreline, width_m=config.track_width_m)
    r = config.resolution_m
    s = np.linspace(-config.lead_in_m, track.length_m + config.run_out_m, len(centreline) + 2)
    half = 0.5 * config.corridor_width_m
    left, _ = track.pose_at(s, -half)
    right, _ = track.pose_at(s, half)
    pts = np.vstack([left, right])
    lo = np.floor(pts.min(axis=0) / r - 1e-9) * r
    hi = np.ceil(pts.max(axis=0) / r + 1e-9) * r
    nx, ny = (np.round((hi - lo) / r).astype(int) + 1).tolist()
    return (float(lo[0]), float(lo[1])), int(nx), int(ny)


def _track_fields(
    config: TerrainConfig,
    track: Track,
    origin: tuple[float, float],
    nx: int,
    ny: int,
    *,
    station: bool = False,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Lateral offset (and, with ``station``, the station) of every sample, bilinearly
    interpolated from a coarser lattice.

    Both are linear along straights and smooth on bends (radius >= half the corridor), so a
    lattice of ``_LATERAL_LATTICE_M`` interpolates them to millimetres near the track while
    cutting the nearest-point queries ~25-fold.
    """
    r = config.resolution_m
    f = max(1, round(_LATERAL_LATTICE_M / r))
    cx = origin[0] + r * f * np.arange((nx - 1) // f + 2)
    cy = origin[1] + r * f * np.arange((ny - 1) // f + 2)
    reach = max(config.lead_in_m, config.run_out_m) + config.corridor_width_m
    coarse_s, coarse = track_coordinates(
        track, np.stack(np.meshgrid(cx, cy), axis=-1), spacing_m=r, extend_m=reach
    )
    jj = (np.arange(ny) / f)[:, None]
    ii = (np.arange(nx) / f)[None, :]
    where = np.broadcast_arrays(jj, ii)
    lateral = ndimage.map_coordinates(coarse, where, order=1, mode="nearest")
    stations = ndimage.map_coordinates(coarse_s, where, order=1, mode="nearest") if station else None
    return lateral, stations


def generate_terrain(config: TerrainConfig, seed: int) -> Terrain:
    """Build the heightfield, track and obstacle ground truth of ``config`` from ``seed``.

    Raises:
        ConfigError: bad seed, or an obstacle that cannot be carved or lies outside the terrain
            (the field is named like ``"negative_obstacles[0].station_m"``).
    """
    require(
        isinstance(config, TerrainConfig),
        "config",
        f"must be a TerrainConfig, got {type(config).__name__}",
    )
    require(
        isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0,
        "seed",
        f"must be an int >= 0, got {seed!r}",
    )
    rng = np.random.default_rng(int(seed))
    r = config.resolution_m
    centreline = build_centreline(config)
    track = Track(
        centreline_xy_m=centreline,
        width_m=config.track_width_m,
        border_kinds=(config.left_border.kind, config.right_border.kind),
    )
    origin, nx, ny = _grid(config, centreline)
    lateral, stations = _track_fields(config, track, origin, nx, ny, station=bool(config.profile))

    rough = config.roughness
    shape = (ny, nx)
    # Fixed draw order: slopes, bumps, fine. Octaves with zero amplitude still draw (stable streams).
    slopes = rough.slope_amplitude_m * value_noise(rng, shape, r, rough.slope_wavelength_m)
    bumps = rough.bump_amplitude_m * value_noise(rng, shape, r, rough.bump_wavelength_m)
    fine = rough.fine_amplitude_m * value_noise(rng, shape, r, rough.fine_wavelength_m)
    half_w = 0.5 * config.track_width_m
    beyond = np.abs(lateral) - half_w
    t = np.clip(beyond / rough.track_blend_m, 0.0, 1.0)
    weight = rough.track_scale + (1.0 - rough.track_scale) * t * t * (3.0 - 2.0 * t)
    sigma = rough.rut_width_m / 2.3548  # full width at half depth -> Gaussian sigma
    ruts = -rough.rut_depth_m * libm.exp(-0.5 * ((np.abs(lateral) - 0.5 * rough.rut_spacing_m) / sigma) ** 2)
    border = np.where(
        lateral < 0, config.left_border.profile_m(beyond), config.right_border.profile_m(beyond)
    )
    heights = slopes + weight * (bumps + fine) + ruts + border
    # the profile's ranges are drawn after the noise octaves: a course without ranges keeps its streams
    profile = tuple(feature.drawn(rng) for feature in config.profile)
    for feature in profile:
        heights = heights + feature.offset_m(stations)
    heights = heights.astype(np.float32)
    hf = HeightField(heights_m=heights, resolution_m=r, origin_m=origin)

    records: dict[str, list] = {}
    for field_name, specs, build in (
        ("negative_obstacles", config.negative_obstacles, carve_negative_obstacle),
        ("positive_obstacles", config.positive_obstacles, place_positive_obstacle),
    ):
        records[field_name] = []
        for k, spec in enumerate(specs):
            centre, yaw = _place(track, spec.station_m, spec.lateral_m, spec.xy_m, spec.yaw_deg)
            hf, rec = build(
                hf,
                spec,
                centre_xy_m=centre,
                yaw_rad=yaw,
                obstacle_id=f"{spec.kind}-{k}",
                field=f"{field_name}[{k}]",
            )
            records[field_name].append(rec)
    negatives, positives = records["negative_obstacles"], records["positive_obstacles"]

    start_yaw = math.radians(config.start_yaw_deg)
    goal, _ = track.pose_at(track.length_m - config.goal_margin_m)
    logger.debug("terrain %dx%d at %.3f m, seed %d", ny, nx, r, seed)
    return Terrain(
        heightfield=hf,
        track=track,
        negative_obstacles=tuple(negatives),
        positive_obstacles=tuple(positives),
        start_xy_yaw=(float(config.start_xy_m[0]), float(config.start_xy_m[1]), start_yaw),
        goal_xy_m=(float(goal[0]), float(goal[1])),
        seed=int(seed),
        metadata={
            "config": config,
            "corridor_width_m": config.corridor_width_m,
            "profile": profile,  # the crests and dips as drawn (no ranges)
            "border_faces_xy_m": _border_faces(config, track),
        },
    )


def _border_faces(config: TerrainConfig, track: Track) -> dict[str, np.ndarray]:
    """Polyline (N, 2) where each bank or drop-off face begins, keyed "left"/"right".

    Drop-offs are track borders, not carved obstacles, so they have no
    :class:`NegativeObstacle` record; these lines let an evaluation tell a detection of a
    drop-off edge from a false alarm. Verge-only sides are absent.
    """
    s = np.arange(-config.lead_in_m, track.length_m + config.run_out_m + 1e-9, 1.0)
    faces = {}
    for side, sign, border in (("left", -1.0, config.left_border), ("right", 1.0, config.right_border)):
        if border.kind != "verge":
            offset = sign * (0.5 * config.track_width_m + border.verge_width_m)
            faces[side], _ = track.pose_at(s, offset)
    return faces


def _place(
    track: Track,
    station_m: float | None,
    lateral_m: float,
    xy_m: tuple[float, float] | None,
    yaw_deg: float,
) -> tuple[np.ndarray, float]:
    """World centre and yaw of an obstacle placed in track or world coordinates."""
    if station_m is not None:
        xy, yaw = track.pose_at(station_m, lateral_m)
        return np.asarray(xy), float(yaw) + math.radians(yaw_deg)
    if xy_m is None:  # specs validate this; guard against hand-built objects
        raise ConfigError("xy_m", "an obstacle needs station_m or xy_m")
    return np.asarray(xy_m, dtype=np.float64), math.radians(yaw_deg)
