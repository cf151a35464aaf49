"""Poses and frames.

Vehicle frame (both papers): origin at the INS / rear-axle centre on the ground, **Y forward,
X right, Z up**. World frame: Z up. At yaw = 0 the vehicle faces world +Y; positive yaw turns it
left (counter-clockwise seen from above). Positive pitch lifts the nose, positive roll lowers the
right side. The vehicle-to-world rotation is ``Rz(yaw) @ Rx(pitch) @ Ry(roll)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.errors import ScanError


def rotation_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Vehicle-to-world rotation for the module's roll/pitch/yaw convention (radians)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    ry = np.array([[cr, 0.0, sr], [0.0, 1.0, 0.0], [-sr, 0.0, cr]])
    return rz @ rx @ ry


def pose_from_matrix(position: np.ndarray, rotation: np.ndarray) -> Pose:
    """The :class:`Pose` of a vehicle-to-world ``rotation`` (3x3) at ``position``: the inverse of
    :func:`rotation_from_rpy`'s ``Rz(yaw) Rx(pitch) Ry(roll)``."""
    r = np.asarray(rotation, dtype=np.float64)
    roll, pitch = roll_pitch_from_bottom_row(r[2, 0], r[2, 1], r[2, 2])
    yaw = math.atan2(-r[0, 1], r[1, 1])
    return Pose(float(position[0]), float(position[1]), float(position[2]), roll, pitch, yaw)


def roll_pitch_from_bottom_row(r20: float, r21: float, r22: float) -> tuple[float, float]:
    """Roll and pitch [rad] of a vehicle-to-world rotation (as :func:`pose_from_matrix` reads them)
    from its bottom row alone: what a tilt check needs, without building a :class:`Pose`."""
    pitch = math.asin(min(1.0, max(-1.0, float(r21))))  # clipped: rounding can pass +-1
    return math.atan2(-r20, r22), pitch


@dataclass(frozen=True)
class Pose:
    """A 6-DoF pose of the vehicle frame in the world frame: position [m], angles [rad]."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        values = (self.x, self.y, self.z, self.roll, self.pitch, self.yaw)
        if not all(math.isfinite(float(v)) for v in values):
            raise ScanError(f"pose has a non-finite component: {values}")

    @property
    def rotation(self) -> np.ndarray:
        """3x3 vehicle-to-world rotation."""
        return rotation_from_rpy(self.roll, self.pitch, self.yaw)

    @property
    def translation(self) -> np.ndarray:
        """Vehicle origin in the world frame, shape (3,)."""
        return np.array([self.x, self.y, self.z])

    @property
    def heading(self) -> np.ndarray:
        """Unit vector of the vehicle's forward (+Y) axis projected on the world XY plane."""
        return np.array([-math.sin(self.yaw), math.cos(self.yaw)])

    def to_world(self, points_vehicle: np.ndarray) -> np.ndarray:
        """Map points (..., 3) from the vehicle frame to the world frame."""
        return np.asarray(points_vehicle) @ self.rotation.T + self.translation

    def to_vehicle(self, points_world: np.ndarray) -> np.ndarray:
        """Map points (..., 3) from the world frame to the vehicle frame."""
        return (np.asarray(points_world) - self.translation) @ self.rotation

    def as_array(self) -> np.ndarray:
        """(x, y, z, roll, pitch, yaw) as a float64 array."""
        return np.array([self.x, self.y, self.z, self.roll, self.pitch, self.yaw])

    @classmethod
    def from_array(cls, values: np.ndarray | tuple[float, ...]) -> Pose:
        """Build from (x, y, z, roll, pitch, yaw); raises ``ScanError`` on a wrong length or NaN."""
        arr = np.asarray(values, dtype=float).reshape(-1)
        if arr.shape != (6,):
            raise ScanError(f"pose needs 6 values (x, y, z, roll, pitch, yaw), got shape {arr.shape}")
        return cls(*(float(v) for v in arr))
