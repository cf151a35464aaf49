"""KITTI odometry poses and calibration turned into the vehicle's poses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.core.pose import Pose
from negobs_gym.detector.io import ScanSetup, pose_from_ros
from negobs_gym.detector.io.kitti import kitti_vehicle_poses, read_kitti_poses, read_kitti_velo_to_cam
from negobs_gym.errors import ScanError

# KITTI odometry sequence 00's Velodyne-to-camera calibration (calib.txt, "Tr:")
TR_00 = np.array(
    [
        [4.276802385584e-04, -9.999672484946e-01, -8.084491683471e-03, -1.198459927713e-02],
        [-7.210626507497e-03, 8.081198471645e-03, -9.999413164504e-01, -5.403984729748e-02],
        [9.999738645903e-01, 4.859485810390e-04, -7.206933692422e-03, -2.921968648686e-01],
    ]
)
SETUP = ScanSetup(translation_m=(0.0, 0.3, 1.73))  # an upright sensor 1.73 m up, 0.3 m ahead


def _write(path, matrices: np.ndarray) -> None:
    path.write_text("\n".join(" ".join(f"{v:.12e}" for v in m[:3].reshape(-1)) for m in matrices) + "\n")


def _camera_poses(vehicles: list[Pose], tr: np.ndarray, setup: ScanSetup) -> np.ndarray:
    """The camera poses a KITTI file would hold for these vehicle poses (the inverse map)."""
    from negobs_gym.detector.io.kitti import CAMERA_TO_WORLD, PACKAGE_TO_ROS_BODY

    out = []
    tr4 = np.vstack([tr, [0.0, 0.0, 0.0, 1.0]])
    for v in vehicles:
        r_sensor = v.rotation @ np.asarray(setup.rotation)
        t_sensor = v.translation + v.rotation @ np.asarray(setup.translation_m)
        velo = np.eye(4)
        velo[:3, :3] = CAMERA_TO_WORLD.T @ r_sensor @ PACKAGE_TO_ROS_BODY.T
        velo[:3, 3] = CAMERA_TO_WORLD.T @ t_sensor
        out.append(velo @ np.linalg.inv(tr4))
    return np.stack(out)


def test_files_round_trip_to_the_vehicle_poses(tmp_path) -> None:
    rng = np.random.default_rng(0)
    vehicles = [
        Pose(x=float(x), y=float(y), z=float(z), roll=float(r), pitch=float(p), yaw=float(w))
        for x, y, z, r, p, w in zip(
            rng.uniform(-50, 50, 30),
            rng.uniform(-50, 50, 30),
            rng.uniform(-2, 2, 30),
            rng.uniform(-0.2, 0.2, 30),
            rng.uniform(-0.2, 0.2, 30),
            rng.uniform(-math.pi, math.pi, 30),
            strict=True,
        )
    ]
    _write(tmp_path / "00.txt", _camera_poses(vehicles, TR_00, SETUP))
    (tmp_path / "calib.txt").write_text(
        "P0: " + " ".join(["1.0"] * 12) + "\nTr: " + " ".join(map(str, TR_00.ravel()))
    )
    got = kitti_vehicle_poses(
        read_kitti_poses(tmp_path / "00.txt"), read_kitti_velo_to_cam(tmp_path / "calib.txt"), SETUP
    )
    for want, pose in zip(vehicles, got, strict=True):
        np.testing.assert_allclose(pose.translation, want.translation, atol=1e-6)
        np.testing.assert_allclose(pose.rotation, want.rotation, atol=1e-9)


def test_a_drive_along_the_camera_axis_is_a_drive_forward() -> None:
    """The nominal calibration (Velodyne x forward = camera z): 1 m per frame along the first
    camera's z axis is 1 m per frame along the world's x axis, facing it, as pose_from_ros says;
    the sensor's mounting puts the vehicle 1.73 m below and 0.3 m behind it."""
    nominal = np.array([[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0, 0, 0, 1.0]])
    cameras = np.tile(np.eye(4), (3, 1, 1))
    cameras[:, 2, 3] = [0.0, 1.0, 2.0]
    for k, pose in enumerate(kitti_vehicle_poses(cameras, nominal, SETUP)):
        want = pose_from_ros(k - 0.3, 0.0, -1.73, 0.0, 0.0, 0.0)
        np.testing.assert_allclose(pose.as_array(), want.as_array(), atol=1e-12)


def test_bad_files_are_named(tmp_path) -> None:
    (tmp_path / "short.txt").write_text("1 0 0 0 0 1 0 0 0 0 1\n")
    with pytest.raises(ScanError, match=r"short.txt: line 1: a pose needs 12 finite numbers, got 11"):
        read_kitti_poses(tmp_path / "short.txt")
    (tmp_path / "empty.txt").write_text("\n")
    with pytest.raises(ScanError, match="no poses"):
        read_kitti_poses(tmp_path / "empty.txt")
    (tmp_path / "calib.txt").write_text("P0: 1 2 3\n")
    with pytest.raises(ScanError, match="no Tr: or Tr_velo_to_cam: line"):
        read_kitti_velo_to_cam(tmp_path / "calib.txt")
    (tmp_path / "calib2.txt").write_text("Tr_velo_to_cam: 1 0 0 0 0 1 0 0 0 0 1 nan\n")
    with pytest.raises(ScanError, match="line 1: Tr_velo_to_cam needs 12 finite numbers"):
        read_kitti_velo_to_cam(tmp_path / "calib2.txt")
    with pytest.raises(ScanError, match="cannot read"):
        read_kitti_poses(tmp_path / "missing.txt")
