"""LiDAR sensor models as data: per-laser elevations, azimuth resolution, FOV, range limits.

Importable without pybullet so recorded-data users can use the tables. Lasers are stored in
detector order (docs/sensors.md): ascending elevation, so for an upright sensor a lower index is a
nearer ground hit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from negobs_gym.errors import require
from negobs_gym.sensors.calibration import HDL64E_S2_SZTAKI_VERT_CORRECTION_RAD


@dataclass(frozen=True, kw_only=True)
class LidarModel:
    """One spinning (or scanning) LiDAR model.

    Attributes:
        name: Model name.
        elevation_deg: Per-laser elevation angles [deg]; sorted ascending on construction.
        azimuth_resolution_deg: Column spacing [deg].
        hfov_deg: Horizontal field of view [deg], centred on sensor +Y; 360 = full spin.
        min_range_m: Returns nearer than this are dropped [m].
        max_range_m: Returns farther than this are dropped [m].
        rotation_rate_hz: Spin (frame) rate [Hz].
    """

    name: str
    elevation_deg: tuple[float, ...]
    azimuth_resolution_deg: float
    hfov_deg: float = 360.0
    min_range_m: float = 0.9
    max_range_m: float = 120.0
    rotation_rate_hz: float = 10.0

    def __post_init__(self) -> None:
        el = np.asarray(self.elevation_deg, dtype=np.float64)
        require(el.ndim == 1 and el.size > 0, "elevation_deg", "needs at least one laser")
        require(bool(np.isfinite(el).all()), "elevation_deg", "must be finite")
        require(bool((np.abs(el) < 90.0).all()), "elevation_deg", "must lie in (-90, 90) deg")
        require(np.unique(el).size == el.size, "elevation_deg", "must not repeat a laser")
        object.__setattr__(self, "elevation_deg", tuple(float(v) for v in np.sort(el)))
        r = self.azimuth_resolution_deg
        require(math.isfinite(r) and r > 0.0, "azimuth_resolution_deg", "must be > 0")
        f = self.hfov_deg
        require(math.isfinite(f) and 0.0 < f <= 360.0, "hfov_deg", "must be in (0, 360]")
        require(r <= f, "azimuth_resolution_deg", "must not exceed hfov_deg")
        require(math.isfinite(self.min_range_m) and self.min_range_m >= 0.0, "min_range_m", "must be >= 0")
        require(
            math.isfinite(self.max_range_m) and self.max_range_m > self.min_range_m,
            "max_range_m",
            "must be finite and > min_range_m",
        )
        require(
            math.isfinite(self.rotation_rate_hz) and self.rotation_rate_hz > 0.0,
            "rotation_rate_hz",
            "must be > 0",
        )

    @property
    def n_lasers(self) -> int:
        """Number of lasers (rows of a scan)."""
        return len(self.elevation_deg)

    @property
    def elevation_rad(self) -> np.ndarray:
        """(lasers,) elevations [rad], ascending."""
        return np.deg2rad(np.asarray(self.elevation_deg))

    @property
    def azimuth_rad(self) -> np.ndarray:
        """(columns,) strictly increasing firing azimuths [rad], centred on sensor +Y (read-only:
        one table per resolution and field of view, shared by every scan)."""
        return _azimuths(self.azimuth_resolution_deg, self.hfov_deg)

    @property
    def n_columns(self) -> int:
        """Number of columns of a scan."""
        return int(_azimuths(self.azimuth_resolution_deg, self.hfov_deg).size)


@lru_cache(maxsize=32)
def _azimuths(resolution_deg: float, hfov_deg: float) -> np.ndarray:
    """Firing azimuths [rad] of a model (scans ask for them several times a frame)."""
    if hfov_deg >= 360.0:
        n = round(360.0 / resolution_deg)
        az = -180.0 + resolution_deg * np.arange(n)
    else:
        n = math.floor(hfov_deg / resolution_deg + 1e-9) + 1
        az = -0.5 * hfov_deg + resolution_deg * np.arange(n)
    az = np.deg2rad(az)
    az.flags.writeable = False
    return az


def hdl64e_s2(azimuth_resolution_deg: float = 0.09) -> LidarModel:
    """HDL-64E S2 with a real unit's per-laser vertical angles (the default of paper N's rig).

    The 64 angles are the calibration of one public unit (-24.85 to +4.97 deg, two interleaved
    blocks; see :mod:`negobs_gym.sensors.calibration` for the source). 0.09 deg at 10 Hz gives
    4000 columns x 64 = 256k rays per revolution (paper N §2, docs/sensors.md).
    """
    return LidarModel(
        name="hdl64e_s2",
        elevation_deg=tuple(math.degrees(v) for v in HDL64E_S2_SZTAKI_VERT_CORRECTION_RAD),
        azimuth_resolution_deg=azimuth_resolution_deg,
        min_range_m=0.9,
        max_range_m=120.0,  # datasheet 120 m
        rotation_rate_hz=10.0,
    )


def hdl64e_s2_nominal(azimuth_resolution_deg: float = 0.09) -> LidarModel:
    """HDL-64E S2 with the nominal datasheet span +2 to -24.8 deg, uniform spacing (paper N §2).

    Named alternative to :func:`hdl64e_s2`'s real calibration table. 0.09 deg at 10 Hz gives
    4000 columns x 64 = 256k rays per revolution.
    """
    return LidarModel(
        name="hdl64e_s2_nominal",
        elevation_deg=tuple(np.linspace(-24.8, 2.0, 64)),
        azimuth_resolution_deg=azimuth_resolution_deg,
        min_range_m=0.9,
        max_range_m=120.0,  # datasheet 120 m
        rotation_rate_hz=10.0,
    )


def hdl32e(azimuth_resolution_deg: float = 0.16) -> LidarModel:
    """HDL-32E: 32 lasers -30.67 to +10.67 deg in 4/3 deg steps, 0.16 deg at 10 Hz (72k rays)."""
    return LidarModel(
        name="hdl32e",
        elevation_deg=tuple(np.linspace(-30.67, 10.67, 32)),  # datasheet span, ~4/3 deg steps
        azimuth_resolution_deg=azimuth_resolution_deg,
        min_range_m=1.0,
        max_range_m=100.0,  # datasheet 80-100 m
        rotation_rate_hz=10.0,
    )


def ibeo_lux(
    azimuth_resolution_deg: float = 0.25, hfov_deg: float = 85.0, rotation_rate_hz: float = 25.0
) -> LidarModel:
    """IBEO LUX: 4 layers at -1.2, -0.4, +0.4, +1.2 deg, 85 (up to 110) deg FOV (paper T §2)."""
    require(
        azimuth_resolution_deg in (0.125, 0.25, 0.5), "azimuth_resolution_deg", "LUX offers 0.125/0.25/0.5"
    )
    require(rotation_rate_hz in (12.5, 25.0, 50.0), "rotation_rate_hz", "LUX offers 12.5/25/50 Hz")
    require(0.0 < hfov_deg <= 110.0, "hfov_deg", "LUX FOV is at most 110 deg")
    return LidarModel(
        name="ibeo_lux",
        elevation_deg=(-1.2, -0.4, 0.4, 1.2),
        azimuth_resolution_deg=azimuth_resolution_deg,
        hfov_deg=hfov_deg,
        min_range_m=0.3,
        max_range_m=200.0,
        rotation_rate_hz=rotation_rate_hz,
    )
