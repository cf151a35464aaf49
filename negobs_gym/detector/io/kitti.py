"""KITTI odometry poses and raw OXTS fixes: the vehicle's pose at each Velodyne frame of a drive.

A KITTI odometry sequence gives, per frame, the left camera's pose in the first frame's camera
frame (``poses/NN.txt``: 12 numbers a line, a row-major 3x4 ``[R | t]``; camera axes x right, y
down, z forward) and, in ``sequences/NN/calib.txt``, the Velodyne-to-camera transform (``Tr:``, or
``Tr_velo_to_cam:`` in the tracking benchmark). The Velodyne's pose is ``pose @ Tr``; turned into a
z-up world (x forward, y left: the first camera frame's z and -x) and into this package's sensor
axes, the vehicle's pose is the sensor's less its mounting (:class:`ScanSetup`), so that the
detector places the sensor where it was.

A KITTI raw drive gives instead one OXTS (GPS/IMU) fix per frame (``oxts/data/NNNNNNNNNN.txt``:
latitude, longitude, altitude, roll, pitch, yaw first, then 24 more values) and, in the date
folder, the IMU-to-Velodyne transform (``calib_imu_to_velo.txt``: ``R:`` 9 numbers row-major,
``T:`` 3). As KITTI's devkit does (``convertOxtsToPose``), each fix becomes a position by the
Mercator projection scaled at the first fix's latitude (x east, y north, z the altitude) and the
IMU's orientation ``Rz(yaw) Ry(pitch) Rx(roll)`` (IMU axes x forward, y left, z up: ROS body
axes); the Velodyne's pose is the IMU's composed with the calibration's inverse, and the
vehicle's pose the sensor's less its mounting, as above. Positions are taken relative to the first
frame's vehicle (Mercator metres are millions). No data is shipped: KITTI's licence is
non-commercial.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from negobs_gym.core.pose import Pose, pose_from_matrix
from negobs_gym.detector.io.setup import PACKAGE_TO_ROS_BODY, ScanSetup
from negobs_gym.errors import ScanError

__all__ = [
    "kitti_oxts_vehicle_poses",
    "kitti_vehicle_poses",
    "oxts_imu_poses",
    "read_kitti_imu_to_velo",
    "read_kitti_oxts",
    "read_kitti_poses",
    "read_kitti_velo_to_cam",
]

# the first camera frame (x right, y down, z forward) in a z-up world (x forward, y left, z up)
CAMERA_TO_WORLD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
CALIB_KEYS = ("Tr", "Tr_velo_to_cam")
EARTH_RADIUS_M = 6378137.0  # the devkit's Mercator radius (WGS-84 equatorial)
OXTS_FIELDS = 30  # lat, lon, alt, roll, pitch, yaw, then velocities, accelerations, accuracies


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
    world = np.tile(np.eye(4), (len(velo), 1, 1))
    world[:, :3, :3] = CAMERA_TO_WORLD @ velo[:, :3, :3]
    world[:, :3, 3] = velo[:, :3, 3] @ CAMERA_TO_WORLD.T
    r_vehicle, t_vehicle = _vehicle_from_sensor(world, setup)
    return [pose_from_matrix(t, r) for t, r in zip(t_vehicle, r_vehicle, strict=True)]


def _vehicle_from_sensor(sensor_in_world: np.ndarray, setup: ScanSetup) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3, 3) rotations and (N, 3) positions of the vehicle, given the (N, 4, 4) poses of the
    sensor (ROS body axes) in a z-up world: the sensor's pose in this package's axes, less its
    mounting in ``setup``."""
    r_sensor = sensor_in_world[:, :3, :3] @ PACKAGE_TO_ROS_BODY
    mount_r, mount_t = np.asarray(setup.rotation, dtype=float), np.asarray(setup.translation_m, dtype=float)
    r_vehicle = r_sensor @ mount_r.T  # the mounting is sensor-to-vehicle
    return r_vehicle, sensor_in_world[:, :3, 3] - r_vehicle @ mount_t


def read_kitti_imu_to_velo(path: str | os.PathLike[str]) -> np.ndarray:
    """The 4x4 IMU-to-Velodyne transform of a KITTI raw ``calib_imu_to_velo.txt`` (``R:``, ``T:``).

    Raises:
        ScanError: an unreadable file, a missing ``R`` or ``T`` line, or one with other than 9 / 3
            finite numbers.
    """
    name = os.fspath(path)
    found: dict[str, np.ndarray] = {}
    for n, line in enumerate(_lines(path, "the calibration"), start=1):
        key, sep, rest = line.partition(":")
        if sep and key.strip() in ("R", "T"):
            size = 9 if key.strip() == "R" else 3
            found[key.strip()] = _numbers(rest, key.strip(), size, f"{name}: line {n}")
    missing = [k + ":" for k in ("R", "T") if k not in found]
    if missing:
        raise ScanError(f"{name}: no {' or '.join(missing)} line (a KITTI raw calib_imu_to_velo.txt)")
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = found["R"].reshape(3, 3), found["T"]
    return out


def read_kitti_oxts(folder: str | os.PathLike[str]) -> np.ndarray:
    """The (N, 6) ``lat, lon, alt, roll, pitch, yaw`` of a KITTI raw ``oxts`` folder (or its
    ``data`` folder): one ``.txt`` per frame, in file-name order (degrees, metres, radians).

    Raises:
        ScanError: no such folder or no ``.txt`` in it, or a file whose line is not 30 finite
            numbers (named).
    """
    root = Path(folder)
    data = root / "data" if (root / "data").is_dir() else root
    if not data.is_dir():
        raise ScanError(f"{os.fspath(folder)}: not a folder (a KITTI raw drive's oxts or oxts/data)")
    files = sorted(data.glob("*.txt"))
    if not files:
        raise ScanError(f"{os.fspath(data)}: no OXTS .txt files")
    fixes = []
    for path in files:
        lines = [line for line in _lines(path, "an OXTS fix") if line.strip()]
        if len(lines) != 1:
            raise ScanError(f"{os.fspath(path)}: {len(lines)} lines, one OXTS fix expected")
        fixes.append(_numbers(lines[0], "an OXTS fix", OXTS_FIELDS, os.fspath(path))[:6])
    return np.stack(fixes)


def oxts_imu_poses(fixes: np.ndarray) -> np.ndarray:
    """(N, 4, 4) IMU poses (ROS body axes) of OXTS ``fixes`` (N, 6): Mercator positions scaled at
    the first fix's latitude (x east, y north, z the altitude), ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    from scipy.spatial.transform import Rotation

    f = np.asarray(fixes, dtype=float)
    lat, lon, alt = f[:, 0], f[:, 1], f[:, 2]
    scale = np.cos(np.radians(lat[0]))
    poses = np.tile(np.eye(4), (len(f), 1, 1))
    poses[:, 0, 3] = scale * EARTH_RADIUS_M * np.radians(lon)
    poses[:, 1, 3] = scale * EARTH_RADIUS_M * np.log(np.tan(np.radians(90.0 + lat) / 2.0))
    poses[:, 2, 3] = alt
    poses[:, :3, :3] = Rotation.from_euler("ZYX", f[:, [5, 4, 3]]).as_matrix()  # Rz @ Ry @ Rx
    return poses


def kitti_oxts_vehicle_poses(fixes: np.ndarray, imu_to_velo: np.ndarray, setup: ScanSetup) -> list[Pose]:
    """The vehicle's :class:`Pose` at each OXTS fix: the Velodyne's pose (the IMU's composed with
    ``imu_to_velo``'s inverse) less the sensor's mounting in ``setup``, positions relative to the
    first frame's vehicle."""
    velo = oxts_imu_poses(fixes) @ np.linalg.inv(np.asarray(imu_to_velo, dtype=float))
    r_vehicle, t_vehicle = _vehicle_from_sensor(velo, setup)
    t_vehicle = t_vehicle - t_vehicle[0]
    return [pose_from_matrix(t, r) for t, r in zip(t_vehicle, r_vehicle, strict=True)]
