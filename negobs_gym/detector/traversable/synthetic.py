"""Analytic 4-layer LUX scans of simple scenes, for tests and benchmarks (numpy only).

A scene is flat ground along vehicle +Y between two borders (earth banks rising at a slope, or
drop-offs), optionally bending, with axis-aligned boxes standing on it. Rays are marched through
the height field in fixed steps and refined by bisection, all rays at once; boxes are intersected
analytically (slab test). Vehicle pitch/roll relative to the ground (bouncing) and range noise
come from the caller; noise only from an explicit ``np.random.Generator``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from negobs_gym.core import libm
from negobs_gym.core.pose import Pose, rotation_from_rpy
from negobs_gym.core.scan import StructuredScan, ray_directions
from negobs_gym.errors import ConfigError, require


@dataclass(frozen=True, kw_only=True)
class LuxRig:
    """IBEO LUX mount and scan pattern (paper T §2 and §4)."""

    elevations_deg: tuple[float, ...] = (-1.2, -0.4, 0.4, 1.2)  # Eq. 3, detector order (lowest first)
    height_m: float = 0.65  # §4: mounted 65 cm above ground
    pitch_down_deg: float = 5.03  # §4: pitched down 5.03 deg
    forward_m: float = 3.7  # front bumper of a 4.5 m vehicle, from the rear axle (docs/physics.md)
    fov_deg: float = 110.0  # §4: 85 deg, extendable to 110 deg
    resolution_deg: float = 0.25  # §4: 0.125 / 0.25 / 0.5 deg
    max_range_m: float = 60.0  # LUX reaches 200 m; 60 m covers every ground hit of this mount

    def __post_init__(self) -> None:
        for name in ("height_m", "fov_deg", "resolution_deg", "max_range_m"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value}")
        require(len(self.elevations_deg) >= 1, "elevations_deg", "needs at least one laser")

    @property
    def rotation(self) -> np.ndarray:
        """Sensor-to-vehicle rotation: pitched down about the X axis."""
        return rotation_from_rpy(0.0, -math.radians(self.pitch_down_deg), 0.0)

    @property
    def translation_m(self) -> np.ndarray:
        """Sensor origin in the vehicle frame [m]."""
        return np.array([0.0, self.forward_m, self.height_m])

    @property
    def azimuth_rad(self) -> np.ndarray:
        """Column azimuths, symmetric about +Y, ``fov / resolution + 1`` columns."""
        n = round(self.fov_deg / self.resolution_deg) + 1
        return np.radians(np.linspace(-self.fov_deg / 2, self.fov_deg / 2, n))


@dataclass(frozen=True, kw_only=True)
class Box:
    """Axis-aligned box standing on the ground: centre (x, y), size along X and Y, height [m]."""

    x_m: float
    y_m: float
    size_x_m: float
    size_y_m: float
    height_m: float


@dataclass(frozen=True, kw_only=True)
class Bump:
    """One sinusoidal ground undulation ``amplitude * sin(kx x + ky y + phase)`` [m, rad/m]."""

    kx_rad_m: float
    ky_rad_m: float
    phase_rad: float
    amplitude_m: float


def random_bumps(
    rng: np.random.Generator, amplitude_m: float, wavelength_m: float, count: int = 8
) -> tuple[Bump, ...]:
    """``count`` random undulations of about ``wavelength_m`` whose sum has RMS ``amplitude_m``."""
    k = 2 * np.pi / wavelength_m
    kx, ky = rng.uniform(-k, k, size=(2, count))
    phase = rng.uniform(0, 2 * np.pi, size=count)
    amp = amplitude_m * math.sqrt(2.0 / count)
    return tuple(
        Bump(kx_rad_m=a, ky_rad_m=b, phase_rad=c, amplitude_m=amp)
        for a, b, c in zip(kx, ky, phase, strict=True)
    )


@dataclass(frozen=True, kw_only=True)
class TrackScene:
    """A track along +Y: road half-widths, border kind, optional bend, boxes (vehicle frame)."""

    left_half_width_m: float = 4.0
    right_half_width_m: float = 4.0
    border: Literal["bank", "drop"] = "bank"
    bank_slope_deg: float = 45.0
    bank_height_m: float = 1.0
    drop_depth_m: float = 3.0
    # Signed bend radius of the centre line [m]: > 0 bends right, < 0 left, None straight.
    bend_radius_m: float | None = None
    # Road crown: the centre line this much higher than the road edges (paper T Fig. 10) [m].
    crown_m: float = 0.0
    # Two wheel ruts along the track (docs/terrain.md): depth [m], centres at +-rut_spacing_m / 2.
    rut_depth_m: float = 0.0
    rut_spacing_m: float = 1.7
    bumps: tuple[Bump, ...] = ()
    # Distance driven: ruts/bumps are evaluated at y + travelled_m (the ground moves past the car).
    travelled_m: float = 0.0
    boxes: tuple[Box, ...] = ()

    def __post_init__(self) -> None:
        for name in ("left_half_width_m", "right_half_width_m", "bank_height_m", "drop_depth_m"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value}")
        require(
            0 < self.bank_slope_deg <= 90, "bank_slope_deg", f"must be in (0, 90], got {self.bank_slope_deg}"
        )
        require(self.border in ("bank", "drop"), "border", f"must be 'bank' or 'drop', got {self.border!r}")
        if self.bend_radius_m is not None:
            require(
                math.isfinite(self.bend_radius_m) and abs(self.bend_radius_m) > 1.0,
                "bend_radius_m",
                f"must be finite with |R| > 1 m, got {self.bend_radius_m}",
            )

    def centre_x(self, y_m: np.ndarray) -> np.ndarray:
        """Centre-line lateral position at forward distance y [m]."""
        y = np.asarray(y_m, dtype=np.float64)
        if self.bend_radius_m is None:
            return np.zeros_like(y)
        r = abs(self.bend_radius_m)
        yc = np.clip(y, -0.999 * r, 0.999 * r)
        return math.copysign(1.0, self.bend_radius_m) * (r - np.sqrt(r * r - yc * yc))

    def left_edge_x(self, y_m: np.ndarray) -> np.ndarray:
        """True left road edge at y [m]."""
        return self.centre_x(y_m) - self.left_half_width_m

    def right_edge_x(self, y_m: np.ndarray) -> np.ndarray:
        """True right road edge at y [m]."""
        return self.centre_x(y_m) + self.right_half_width_m

    def height(self, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
        """Ground height (boxes excluded) at (x, y) [m]."""
        e = np.asarray(x_m) - self.centre_x(y_m)
        outside = np.maximum(np.maximum(e - self.right_half_width_m, -self.left_half_width_m - e), 0.0)
        half = np.where(e < 0, self.left_half_width_m, self.right_half_width_m)
        crown = self.crown_m * np.clip(1.0 - (e / half) ** 2, 0.0, 1.0)
        if self.rut_depth_m > 0:
            crown = crown - self.rut_depth_m * libm.exp(
                -0.5 * ((np.abs(e) - self.rut_spacing_m / 2) / 0.17) ** 2
            )
        if self.bumps:
            yy = np.asarray(y_m) + self.travelled_m
            for b in self.bumps:  # a few sinusoids, each vectorized over all samples
                crown = crown + b.amplitude_m * np.sin(
                    b.kx_rad_m * np.asarray(x_m) + b.ky_rad_m * yy + b.phase_rad
                )
        if self.border == "bank":
            return crown + np.minimum(
                outside * math.tan(math.radians(self.bank_slope_deg)), self.bank_height_m
            )
        return np.where(outside > 0, -self.drop_depth_m, crown)


def _march_terrain(scene: TrackScene, origin: np.ndarray, dirs: np.ndarray, max_range_m: float) -> np.ndarray:
    """First ground crossing along each ray (n, 3), NaN if none within ``max_range_m``."""
    step = 0.1
    t = np.arange(step, max_range_m + step, step)
    p = origin + t[None, :, None] * dirs[:, None, :]  # (n, T, 3)
    below = p[..., 2] <= scene.height(p[..., 0], p[..., 1])
    hit = below.any(axis=1)
    first = below.argmax(axis=1)
    lo = np.where(first > 0, t[np.maximum(first - 1, 0)], 0.0)
    hi = t[first]
    for _ in range(12):  # bisection to ~0.03 mm
        mid = 0.5 * (lo + hi)
        q = origin + mid[:, None] * dirs
        under = q[:, 2] <= scene.height(q[:, 0], q[:, 1])
        hi = np.where(under, mid, hi)
        lo = np.where(under, lo, mid)
    return np.where(hit, hi, np.nan)


def _hit_boxes(boxes: tuple[Box, ...], origin: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Nearest entry distance of each ray (n, 3) into any box (slab test), NaN if none."""
    best = np.full(dirs.shape[0], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for b in boxes:  # a few boxes; each test is vectorized over all rays
            lo = np.array([b.x_m - b.size_x_m / 2, b.y_m - b.size_y_m / 2, 0.0])
            hi = np.array([b.x_m + b.size_x_m / 2, b.y_m + b.size_y_m / 2, b.height_m])
            t1 = (lo - origin) * inv
            t2 = (hi - origin) * inv
            t_near = np.nanmax(np.minimum(t1, t2), axis=1)
            t_far = np.nanmin(np.maximum(t1, t2), axis=1)
            ok = (t_near <= t_far) & (t_far > 0) & (t_near > 0)
            best = np.where(ok & (t_near < best), t_near, best)
    return np.where(np.isfinite(best), best, np.nan)


def synthetic_scan(
    scene: TrackScene,
    rig: LuxRig | None = None,
    *,
    vehicle_pitch_rad: float = 0.0,
    vehicle_roll_rad: float = 0.0,
    range_noise_m: float = 0.0,
    rng: np.random.Generator | None = None,
    pose: Pose | None = None,
) -> StructuredScan:
    """Cast the LUX rig into ``scene``; the vehicle may be pitched/rolled relative to the ground.

    Args:
        scene: The track.
        rig: LUX mount (default :class:`LuxRig`).
        vehicle_pitch_rad: Vehicle pitch relative to the ground (bouncing), nose up positive.
        vehicle_roll_rad: Vehicle roll relative to the ground.
        range_noise_m: Gaussian range noise sigma; needs ``rng`` when > 0.
        rng: Source of the noise.
        pose: Pose stored in the scan (default identity).

    Returns:
        A :class:`StructuredScan` named ``"lux"``; ranges in the sensor frame, NaN = no return.
    """
    rig = rig if rig is not None else LuxRig()
    if range_noise_m > 0 and rng is None:
        raise ConfigError("rng", "range_noise_m > 0 needs an explicit rng (np.random.Generator)")
    el = np.radians(np.asarray(rig.elevations_deg, dtype=np.float64))
    az = rig.azimuth_rad
    d_sensor = ray_directions(el, az).reshape(-1, 3)
    body = rotation_from_rpy(vehicle_roll_rad, vehicle_pitch_rad, 0.0)  # vehicle -> ground frame
    dirs = d_sensor @ (body @ rig.rotation).T
    origin = body @ rig.translation_m
    t = np.fmin(_march_terrain(scene, origin, dirs, rig.max_range_m), _hit_boxes(scene.boxes, origin, dirs))
    if range_noise_m > 0:
        t = t + rng.normal(0.0, range_noise_m, size=t.shape)
    t = np.where(t > rig.max_range_m, np.nan, np.abs(t))
    return StructuredScan(
        sensor="lux",
        ranges_m=t.reshape(el.size, az.size),
        azimuth_rad=az,
        elevation_rad=el,
        rotation=rig.rotation,
        translation_m=rig.translation_m,
        pose=pose if pose is not None else Pose(),
    )
