"""Sensor rigs: models mounted on the vehicle with extrinsics ``P_V = R P_L + T``.

Presets: paper N's rig (upright HDL-64 at 2.2 m, two HDL-32E rolled 90 deg at the sides),
paper T's rig (IBEO LUX on the bumper at 0.65 m pitched down 5.03 deg), and reduced-resolution
variants for RL training.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.core.pose import rotation_from_rpy
from negobs_gym.errors import UnknownNameError, require
from negobs_gym.sensors.models import LidarModel, hdl32e, hdl64e_s2, ibeo_lux


@dataclass(frozen=True, kw_only=True)
class SensorMount:
    """One sensor on the vehicle.

    Attributes:
        name: Key of the sensor in a rig (``"hdl64"``, ``"hdl32_left"``...).
        model: The LiDAR model.
        rotation: Sensor-to-vehicle rotation R as 9 row-major values; must be orthonormal.
        translation_m: Sensor origin in the vehicle frame T [m] (z above the ground plane).
    """

    name: str
    model: LidarModel
    rotation: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    translation_m: tuple[float, float, float] = (0.0, 0.0, 2.2)

    def __post_init__(self) -> None:
        require(bool(self.name), "name", "must be non-empty")
        require(isinstance(self.model, LidarModel), "model", "must be a LidarModel")
        r = np.asarray(self.rotation, dtype=np.float64)
        require(r.size == 9 and bool(np.isfinite(r).all()), "rotation", "needs 9 finite values")
        r = r.reshape(3, 3)
        require(
            bool(np.allclose(r @ r.T, np.eye(3), atol=1e-6)) and np.linalg.det(r) > 0,
            "rotation",
            "must be orthonormal with det +1",
        )
        t = np.asarray(self.translation_m, dtype=np.float64)
        require(t.shape == (3,) and bool(np.isfinite(t).all()), "translation_m", "needs 3 finite values")
        object.__setattr__(self, "rotation", tuple(float(v) for v in r.ravel()))
        object.__setattr__(self, "translation_m", tuple(float(v) for v in t))

    @property
    def rotation_matrix(self) -> np.ndarray:
        """(3, 3) sensor-to-vehicle rotation."""
        return np.asarray(self.rotation, dtype=np.float64).reshape(3, 3)


@dataclass(frozen=True, kw_only=True)
class Rig:
    """A named set of mounted sensors."""

    name: str
    mounts: tuple[SensorMount, ...]

    def __post_init__(self) -> None:
        require(len(self.mounts) > 0, "mounts", "a rig needs at least one sensor")
        names = [m.name for m in self.mounts]
        require(len(set(names)) == len(names), "mounts", f"duplicate sensor names {names}")

    def mount(self, name: str) -> SensorMount:
        """The mount called ``name``."""
        for m in self.mounts:
            if m.name == name:
                return m
        names = [m.name for m in self.mounts]
        raise UnknownNameError(f"rig {self.name!r} has no sensor {name!r}; it has {names}")


def _rot(m: np.ndarray) -> tuple[float, ...]:
    return tuple(float(v) for v in m.ravel())


# Side HDL-32 rolled 90 deg (same convention as detector.synthetic.hdl32_side_rotation):
# left: spin axis = vehicle -X, sensor +X = up, azimuth -90 -> 0 deg sweeps the ground near -> far.
SIDE_LEFT_R = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
SIDE_RIGHT_R = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])

#: Paper T's LUX sits on the front bumper (paper T §2); the ALV's body ends 3.65 m ahead of the
#: rear axle (``sim.vehicle.VehicleConfig``: 4.5 m long, 0.85 m behind the axle), the sensor's
#: optical centre 5 cm beyond it [m]
LUX_FORWARD_M = 3.7


def paper_n_rig(
    hdl64: LidarModel | None = None,
    hdl32: LidarModel | None = None,
    hdl64_height_m: float = 2.2,  # paper N §2: HDL-64 2.2 m above ground
    hdl32_height_m: float = 2.0,
    hdl32_half_track_m: float = 0.9,
) -> Rig:
    """Paper N's rig: upright HDL-64 plus left/right HDL-32E rolled 90 deg (lasers sweep radially).

    The HDL-64 defaults to :func:`~negobs_gym.sensors.models.hdl64e_s2` (a real unit's
    calibration); pass ``hdl64=hdl64e_s2_nominal()`` for the uniform datasheet table.
    """
    h64 = hdl64 or hdl64e_s2()
    h32 = hdl32 or hdl32e()
    return Rig(
        name="paper_n",
        mounts=(
            SensorMount(name="hdl64", model=h64, translation_m=(0.0, 0.0, hdl64_height_m)),
            SensorMount(
                name="hdl32_left",
                model=h32,
                rotation=_rot(SIDE_LEFT_R),
                translation_m=(-hdl32_half_track_m, 0.5, hdl32_height_m),
            ),
            SensorMount(
                name="hdl32_right",
                model=h32,
                rotation=_rot(SIDE_RIGHT_R),
                translation_m=(hdl32_half_track_m, 0.5, hdl32_height_m),
            ),
        ),
    )


def paper_t_rig(
    lux: LidarModel | None = None,
    height_m: float = 0.65,  # paper T §2
    pitch_down_deg: float = 5.03,  # paper T §2
    forward_m: float = LUX_FORWARD_M,
) -> Rig:
    """Paper T's rig: IBEO LUX on the front bumper (``forward_m`` ahead of the rear axle) at 0.65 m,
    pitched down 5.03 deg (paper T §2)."""
    require(
        math.isfinite(pitch_down_deg) and abs(pitch_down_deg) < 90.0, "pitch_down_deg", "must be in (-90, 90)"
    )
    require(math.isfinite(forward_m), "forward_m", f"must be finite, got {forward_m!r}")
    r = rotation_from_rpy(0.0, -math.radians(pitch_down_deg), 0.0)
    return Rig(
        name="paper_t",
        mounts=(
            SensorMount(
                name="lux",
                model=lux or ibeo_lux(),
                rotation=_rot(r),
                translation_m=(0.0, forward_m, height_m),
            ),
        ),
    )


def paper_n_rig_reduced(hdl64: LidarModel | None = None) -> Rig:
    """Reduced paper N rig for RL training: every other laser (by elevation) of the HDL-64 at
    0.36 deg, HDL-32 at 0.64 deg. ``hdl64`` defaults to the calibrated :func:`hdl64e_s2`."""
    full = hdl64 or hdl64e_s2()
    h64 = LidarModel(
        name="hdl64e_s2_reduced",
        elevation_deg=full.elevation_deg[::2],
        azimuth_resolution_deg=0.36,
        min_range_m=full.min_range_m,
        max_range_m=full.max_range_m,
    )
    return paper_n_rig(hdl64=h64, hdl32=hdl32e(azimuth_resolution_deg=0.64))
