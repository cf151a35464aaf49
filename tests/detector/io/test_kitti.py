"""KITTI odometry poses and calibration turned into the vehicle's poses."""

from __future__ import annotations

import itertools
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


# KITTI raw 2011_09_26's IMU-to-Velodyne calibration (calib_imu_to_velo.txt)
IMU_TO_VELO_0926 = np.array(
    [
        [9.999976e-01, 7.553071e-04, -2.035826e-03, -8.086759e-01],
        [-7.854027e-04, 9.998898e-01, -1.482298e-02, 3.195559e-01],
        [2.024406e-03, 1.482454e-02, 9.998881e-01, -7.997231e-01],
        [0.0, 0.0, 0.0, 1.0],
    ]
)
KARLSRUHE_LAT, KARLSRUHE_LON, KARLSRUHE_ALT = 49.011, 8.4227, 112.8


def oxts_fixes(vehicles: list[Pose], imu_to_velo: np.ndarray, setup: ScanSetup) -> np.ndarray:
    """The (N, 6) OXTS fixes a KITTI raw drive would hold for these vehicle poses (the inverse map),
    the first vehicle at Karlsruhe."""
    from scipy.spatial.transform import Rotation

    from negobs_gym.detector.io.kitti import EARTH_RADIUS_M, PACKAGE_TO_ROS_BODY

    rows = []
    scale = math.cos(math.radians(KARLSRUHE_LAT))
    east0 = scale * EARTH_RADIUS_M * math.radians(KARLSRUHE_LON)
    north0 = scale * EARTH_RADIUS_M * math.log(math.tan(math.radians(90.0 + KARLSRUHE_LAT) / 2.0))
    for v in vehicles:
        velo = np.eye(4)
        velo[:3, :3] = v.rotation @ np.asarray(setup.rotation) @ PACKAGE_TO_ROS_BODY.T
        velo[:3, 3] = v.translation + v.rotation @ np.asarray(setup.translation_m)
        imu = velo @ imu_to_velo
        east, north, up = imu[:3, 3] + [east0, north0, KARLSRUHE_ALT]
        lon = math.degrees(east / (scale * EARTH_RADIUS_M))
        lat = 2.0 * math.degrees(math.atan(math.exp(north / (scale * EARTH_RADIUS_M)))) - 90.0
        yaw, pitch, roll = Rotation.from_matrix(imu[:3, :3]).as_euler("ZYX")
        rows.append([lat, lon, up, roll, pitch, yaw])
    return np.array(rows)


def write_oxts(folder, fixes: np.ndarray) -> None:
    """One file per fix as KITTI writes them: the 6 pose values, then 24 others (zeros here)."""
    (folder / "data").mkdir(parents=True)
    for k, fix in enumerate(fixes):
        values = [*fix, *([0.0] * 24)]
        (folder / "data" / f"{k:010d}.txt").write_text(" ".join(f"{v:.17g}" for v in values) + "\n")


def write_imu_to_velo(path, transform: np.ndarray) -> None:
    rotation = " ".join(f"{v:.7e}" for v in transform[:3, :3].ravel())
    translation = " ".join(f"{v:.7e}" for v in transform[:3, 3])
    path.write_text(f"calib_time: 25-May-2012 16:47:16\nR: {rotation}\nT: {translation}\n")


def test_oxts_files_round_trip_to_the_vehicle_poses(tmp_path) -> None:
    from negobs_gym.detector.io.kitti import kitti_oxts_vehicle_poses, read_kitti_imu_to_velo, read_kitti_oxts

    rng = np.random.default_rng(1)
    vehicles = [Pose()] + [
        Pose(x=float(x), y=float(y), z=float(z), roll=float(r), pitch=float(p), yaw=float(w))
        for x, y, z, r, p, w in rng.uniform(
            [-500, -500, -5, -0.2, -0.2, -math.pi], [500, 500, 5, 0.2, 0.2, math.pi], (30, 6)
        )
    ]  # the first at the origin: positions are taken relative to it
    write_oxts(tmp_path / "oxts", oxts_fixes(vehicles, IMU_TO_VELO_0926, SETUP))
    write_imu_to_velo(tmp_path / "calib_imu_to_velo.txt", IMU_TO_VELO_0926)
    calib = read_kitti_imu_to_velo(tmp_path / "calib_imu_to_velo.txt")
    np.testing.assert_allclose(calib, IMU_TO_VELO_0926, atol=1e-12)
    fixes = read_kitti_oxts(tmp_path / "oxts")
    assert fixes.shape == (31, 6) and np.array_equal(fixes, read_kitti_oxts(tmp_path / "oxts" / "data"))
    for want, pose in zip(vehicles, kitti_oxts_vehicle_poses(fixes, calib, SETUP), strict=True):
        np.testing.assert_allclose(pose.translation, want.translation, atol=1e-6)  # 1 um over 500 m
        np.testing.assert_allclose(pose.rotation, want.rotation, atol=1e-8)  # the calibration R: ~7 digits


def test_an_imu_heading_north_drives_north() -> None:
    """The identity calibration and an upright sensor at the IMU: fixes 1e-5 deg of latitude apart
    (1.1 m at 49 deg N) with yaw 90 deg (north) are a drive along the world's y axis, facing it."""
    from negobs_gym.detector.io.kitti import kitti_oxts_vehicle_poses

    lat = KARLSRUHE_LAT + 1e-5 * np.arange(3)
    fixes = np.column_stack(
        [lat, np.full(3, KARLSRUHE_LON), np.full(3, 100.0), [0, 0, 0], [0, 0, 0], [math.pi / 2] * 3]
    )
    poses = kitti_oxts_vehicle_poses(fixes, np.eye(4), ScanSetup(translation_m=(0.0, 0.0, 0.0)))
    step = [b.y - a.y for a, b in itertools.pairwise(poses)]
    assert step == pytest.approx([1.112] * 2, abs=0.01) and all(abs(p.x) < 1e-9 for p in poses)
    assert all(p.yaw == pytest.approx(0.0, abs=1e-12) for p in poses)  # this package: yaw 0 faces +y


def test_bad_oxts_and_calibration_files_are_named(tmp_path) -> None:
    from negobs_gym.detector.io.kitti import read_kitti_imu_to_velo, read_kitti_oxts

    with pytest.raises(ScanError, match="not a folder"):
        read_kitti_oxts(tmp_path / "nowhere")
    (tmp_path / "oxts" / "data").mkdir(parents=True)
    with pytest.raises(ScanError, match=r"no OXTS \.txt files"):
        read_kitti_oxts(tmp_path / "oxts")
    (tmp_path / "oxts" / "data" / "0000000000.txt").write_text(" ".join(["1.0"] * 29) + "\n")
    with pytest.raises(ScanError, match=r"0000000000.txt: an OXTS fix needs 30 finite numbers, got 29"):
        read_kitti_oxts(tmp_path / "oxts")
    (tmp_path / "calib.txt").write_text("Tr: " + " ".join(["0"] * 12) + "\n")  # an odometry calib.txt
    with pytest.raises(ScanError, match=r"no R: or T: line \(a KITTI raw calib_imu_to_velo.txt\)"):
        read_kitti_imu_to_velo(tmp_path / "calib.txt")
    (tmp_path / "bad.txt").write_text("R: 1 0 0 0 1 0 0 0 1\nT: 0 0\n")
    with pytest.raises(ScanError, match="line 2: T needs 3 finite numbers, got 2"):
        read_kitti_imu_to_velo(tmp_path / "bad.txt")
