"""LiDAR-over-flat-ground geometry of paper N §2 (Eq. 1-8).

Angles follow paper N Fig. 2/5: ``beta`` is a laser's radial emission angle measured from the
downward vertical (nadir), so a laser with ``beta`` hits flat ground at horizontal distance
``h * tan(beta)`` from a sensor at height ``h``. All functions are vectorized over numpy arrays
(scalars work too), take radians and metres, and return floats/arrays.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from negobs_gym.core import libm
from negobs_gym.errors import ConfigError


def _pos(name: str, value: ArrayLike) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if not np.isfinite(arr).all() or (arr <= 0).any():
        raise ConfigError(name, f"must be finite and > 0, got {value!r}")
    return arr


def nadir_angle_from_elevation(elevation_rad: ArrayLike) -> np.ndarray:
    """Convert a sensor elevation (up positive, from the horizontal) to paper N's ``beta``."""
    return np.pi / 2 + np.asarray(elevation_rad, dtype=np.float64)


def ground_range(height_m: ArrayLike, beta_rad: ArrayLike) -> np.ndarray:
    """Eq. 1: slant range ``r = h / cos(beta)`` to the flat-ground hit (inf past the horizon)."""
    h = _pos("height_m", height_m)
    c = np.cos(np.asarray(beta_rad, dtype=np.float64))
    with np.errstate(divide="ignore"):
        return np.where(c > 0, h / np.where(c > 0, c, 1.0), np.inf)


def ring_radius(height_m: ArrayLike, beta_rad: ArrayLike) -> np.ndarray:
    """Eq. 2: horizontal ring radius ``d = h * tan(beta)`` (inf for rays that miss the ground)."""
    h = _pos("height_m", height_m)
    b = np.asarray(beta_rad, dtype=np.float64)
    hits = (b >= 0) & (b < np.pi / 2)
    return np.where(hits, h * libm.tan(np.where(hits, b, 0.0)), np.inf)


def radial_resolution(height_m: ArrayLike, beta_rad: ArrayLike, dbeta_rad: ArrayLike) -> np.ndarray:
    """Eq. 3: ring gap ``dd_V = h (tan beta - tan(beta - dbeta))`` between adjacent lasers."""
    b = np.asarray(beta_rad, dtype=np.float64)
    return ring_radius(height_m, b) - ring_radius(height_m, b - np.asarray(dbeta_rad))


def lateral_resolution(height_m: ArrayLike, beta_rad: ArrayLike, dalpha_rad: ArrayLike) -> np.ndarray:
    """Eq. 4: chord between adjacent firings of one laser, ``2 h tan(beta) sin(dalpha / 2)``."""
    return 2.0 * ring_radius(height_m, beta_rad) * np.sin(np.asarray(dalpha_rad) / 2.0)


def subtended_angle(height_m: ArrayLike, distance_m: ArrayLike, width_m: ArrayLike) -> np.ndarray:
    """Eq. 5: exact angle [rad] a gap of width ``w`` at horizontal distance ``d`` subtends.

    ``tan(theta) = h w / (h^2 + d (d + w))``.
    """
    h = _pos("height_m", height_m)
    d = np.asarray(distance_m, dtype=np.float64)
    w = np.asarray(width_m, dtype=np.float64)
    return libm.arctan(h * w / (h * h + d * (d + w)))


def subtended_angle_approx(height_m: ArrayLike, distance_m: ArrayLike, width_m: ArrayLike) -> np.ndarray:
    """Eq. 6: far-field approximation ``theta ~ h w / (d (d + w))`` (valid for ``d >> h``)."""
    h = _pos("height_m", height_m)
    d = _pos("distance_m", distance_m)
    w = np.asarray(width_m, dtype=np.float64)
    return h * w / (d * (d + w))


def visible_height_difference(height_m: ArrayLike, distance_m: ArrayLike, width_m: ArrayLike) -> np.ndarray:
    """Eq. 7: height drop visible on the far wall, ``dh = h w / d = w cot(beta)``.

    Paper N's example: ``h = 2.2 m, d = 8 m, w = 0.6 m -> dh ~ 0.165 m``.
    """
    h = _pos("height_m", height_m)
    d = _pos("distance_m", distance_m)
    return h * np.asarray(width_m, dtype=np.float64) / d


def range_jump(width_m: ArrayLike, beta_rad: ArrayLike) -> np.ndarray:
    """Eq. 8: largest range increase over a gap of width ``w``, ``w sqrt(1 + cot^2 beta)``."""
    b = np.asarray(beta_rad, dtype=np.float64)
    return np.asarray(width_m, dtype=np.float64) / np.abs(np.sin(b))
