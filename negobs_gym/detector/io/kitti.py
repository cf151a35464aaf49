"""KITTI odometry poses: the vehicle's pose at each Velodyne frame of a sequence.

A KITTI odometry sequence gives, per frame, the left camera's pose in the first frame's camera
frame (``poses/NN.txt``: 12 numbers a line, a row-major 3x4 ``[R | t]``; camera axes x right, y
down, z forward) and, in ``sequences/NN/calib.txt``, the Velodyne-to-camera transform (``Tr:``, or
``Tr_velo_to_cam:`` in the tracking benchmark). The Velodyne's pose is ``pose @ Tr``; turned into a
z-up world (x forward, y left: the first camera frame's z and -x) and into this package's sensor
axes, the vehicle's pose is the sensor's less its mounting (:class:`ScanSetup`), so that the
detector places the sensor where it was. No data is shipped: KITTI's licence is non-commercial.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from negobs_gym.core.pose import Pose, pose_from_matrix
from negobs_gym.detector.io.setup import ScanSetup
from negobs_gym.errors import ScanError

__all__ = ["kitti_vehicle_poses", "read_kitti_poses", "read_kitti_velo_to_cam"]

# the first camera frame (x right, y down, z forward) in a z-up world (x forward, y left, z up)
CAMERA_TO_WORLD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
# ROS / Velodyne body axes (x forward, y left) from this package's (X right, Y forward): p_ros = B p
PACKAGE_TO_ROS_BODY = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
CALIB_KEYS = ("Tr", "Tr_velo_to_cam")


def _homogeneous(values: np.ndarray) -> np.ndarray:
    out = np.tile(np.eye(4), (*values.shape[:-2], 1, 1))
    out[..., :3, :] = values
    return out


def _numbers(line: str, name: str, n: int, where: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in line.split()])
    except ValueError as error:
        raise ScanError(f"{where}: {name} is not {n} numbers ({error})") from error
    if values.size != n or not np.all(np.isfinite(values)):
        raise ScanError(f"{where}: {name} needs {n} finite numbers, got {values.size}")
    return values


def _lines(path: str | os.PathLike[str], what: str) -> list[str]:
    try:
        return Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise ScanError(f"{os.fspath(path)}: cannot read {what} ({type(error).__name__}: {error})") from error


def read_kitti_velo_to_cam(path: str | os.PathLike[str]) -> np.ndarray:
    """The 4x4 Velodyne-to-camera transform of a KITTI ``calib.txt`` (its ``Tr:`` line).

    Raises:
        ScanError: an unreadable file, no ``Tr`` line, or one that is not 12 finite numbers.
    """
    name = os.fspath(path)
    for n, line in enumerate(_lines(path, "the calibration"), start=1):
        key, sep, rest = line.partition(":")
        if sep and key.strip() in CALIB_KEYS:
            return _homogeneous(_numbers(rest, key.strip(), 12, f"{name}: line {n}").reshape(3, 4))
    raise ScanError(
        f"{name}: no {' or '.join(k + ':' for k in CALIB_KEYS)} line (a KITTI odometry calib.txt)"
    )


def read_kitti_poses(path: str | os.PathLike[str]) -> np.ndarray:
    """The (N, 4, 4) camera poses of a KITTI ``poses/NN.txt``, one per line.

    Raises:
        ScanError: an unreadable or empty file, or a line that is not 12 finite numbers.
    """
    name = os.fspath(path)
    lines = [line for line in _lines(path, "poses") if line.strip()]
    if not lines:
        raise ScanError(f"{name}: no poses (12 numbers a line, a 3x4 [R | t] per frame)")
    rows = [_numbers(line, "a pose", 12, f"{name}: line {n}") for n, line in enumerate(lines, start=1)]
    return _homogeneous(np.stack(rows).reshape(-1, 3, 4))


def kitti_vehicle_poses(camera_poses: np.ndarray, velo_to_cam: np.ndarray, setup: ScanSetup) -> list[Pose]:
    """The vehicle's :class:`Pose` at each frame: the Velodyne's pose (``camera_pose @ velo_to_cam``)
    in the z-up world, in this package's axes, less the sensor's mounting in ``setup``."""
    velo = np.asarray(camera_poses, dtype=float) @ np.asarray(velo_to_cam, dtype=float)
    r_sensor = CAMERA_TO_WORLD @ velo[:, :3, :3] @ PACKAGE_TO_ROS_BODY
    t_sensor = velo[:, :3, 3] @ CAMERA_TO_WORLD.T
    mount_r, mount_t = np.asarray(setup.rotation, dtype=float), np.asarray(setup.translation_m, dtype=float)
    r_vehicle = r_sensor @ mount_r.T  # the mounting is sensor-to-vehicle
    t_vehicle = t_sensor - r_vehicle @ mount_t
    return [pose_from_matrix(t, r) for t, r in zip(t_vehicle, r_vehicle, strict=True)]
