"""Poses of a recorded drive: the ROS convention converted, and the CSV read or refused clearly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.core.pose import Pose
from negobs_gym.detector.io import PoseTrack, pose_from_ros, read_poses_csv
from negobs_gym.errors import ScanError


def _ros_rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """REP-103 body-to-world rotation: fixed-axis roll about x, pitch about y, yaw about z."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_a_ros_pose_places_every_body_point_where_ros_does() -> None:
    rng = np.random.default_rng(0)
    ros_to_vehicle = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])  # (x fwd, y left) -> (X right, Y fwd)
    for _ in range(200):
        t = rng.uniform(-50, 50, 3)
        roll, pitch, yaw = rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-math.pi, math.pi)
        pose = pose_from_ros(*t, roll, pitch, yaw)
        p_ros = rng.uniform(-20, 20, (3, 10))  # points in the ROS body frame
        want = _ros_rotation(roll, pitch, yaw) @ p_ros + t[:, None]
        got = pose.rotation @ (ros_to_vehicle @ p_ros) + pose.translation[:, None]
        np.testing.assert_allclose(got, want, atol=1e-9)
    # facing ROS world +x at yaw 0: this package's heading points along world x
    np.testing.assert_allclose(pose_from_ros(0, 0, 0, 0, 0, 0).heading, [1.0, 0.0], atol=1e-12)


def test_csv_rows_in_order_with_extra_columns_and_spaces(tmp_path) -> None:
    path = tmp_path / "poses.csv"
    path.write_text(
        "timestamp, x, y, z, roll, pitch, yaw\n0.0, 0, 0, 0, 0, 0, 0\n0.1, 1.5, 0.2, 0.1, 0.01, 0.02, 0.3\n"
    )
    poses = read_poses_csv(path)
    assert poses[0] == pose_from_ros(0, 0, 0, 0, 0, 0)
    assert poses[1] == pose_from_ros(1.5, 0.2, 0.1, 0.01, 0.02, 0.3)
    assert all(isinstance(p, Pose) for p in poses)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("", "no poses"),
        ("x,y,z,roll,pitch,yaw\n", "no poses"),
        ("x,y,z,roll,yaw\n0,0,0,0,0\n", r"missing pose columns \['pitch'\]"),
        (
            "x,y,z,roll,pitch,yaw\n0,0,0,0,0,0\n1,nan,0,0,0,0\n",
            r"line 3, column y: not a finite number \('nan'\)",
        ),
        ("x,y,z,roll,pitch,yaw\n0,0,0,0,0,fast\n", r"line 2, column yaw: not a finite number \('fast'\)"),
        ("x,y,z,roll,pitch,yaw\n0,0,0,0,0\n", r"line 2, column yaw: not a finite number \(None\)"),
    ],
)
def test_bad_csv_is_refused_naming_the_problem(tmp_path, text: str, match: str) -> None:
    path = tmp_path / "poses.csv"
    path.write_text(text)
    with pytest.raises(ScanError, match=match):
        read_poses_csv(path)


def test_a_missing_file_is_named(tmp_path) -> None:
    with pytest.raises(ScanError, match=r"none\.csv: cannot read poses"):
        read_poses_csv(tmp_path / "none.csv")


def _quaternion(roll: float, pitch: float, yaw: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("xyz", [roll, pitch, yaw]).as_quat()  # ROS fixed-axis RPY, xyzw


def test_a_track_interpolates_positions_and_orientations() -> None:
    times = np.array([0.0, 0.1, 0.2])
    xyz = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.5, 0.0]])
    q = np.array([_quaternion(0.0, 0.0, 0.0), _quaternion(0.02, -0.04, 0.2), _quaternion(0.0, 0.0, 0.4)])
    track = PoseTrack(times, xyz, q * 3.0)  # not unit length: normalised
    at_knot = track.at(0.1)
    want = pose_from_ros(1.0, 0.0, 0.0, 0.02, -0.04, 0.2)
    np.testing.assert_allclose(
        [at_knot.x, at_knot.y, at_knot.z, at_knot.roll, at_knot.pitch, at_knot.yaw],
        [want.x, want.y, want.z, want.roll, want.pitch, want.yaw],
        atol=1e-9,
    )
    mid = track.at(0.15)
    assert (mid.x, mid.y) == pytest.approx((1.5, 0.25))
    assert mid.yaw == pytest.approx(0.3 - math.pi / 2, abs=2e-3)  # slerp: halfway in yaw
    # within max_gap_s of the ends: the end pose; beyond: an error naming the span
    assert track.at(-0.05).x == 0.0 and track.at(0.28).x == 2.0
    with pytest.raises(ScanError, match=r"no pose at t = 0\.350 s: the poses span 0\.000-0\.200 s"):
        track.at(0.35)
    single = PoseTrack(np.array([5.0]), xyz[:1], q[:1])
    assert single.at(5.05) == pose_from_ros(0, 0, 0, 0, 0, 0)


@pytest.mark.parametrize(
    ("times", "quaternions", "match"),
    [
        ([0.0, 0.0], None, "increase strictly"),
        ([0.0, float("nan")], None, "not finite"),
        ([0.0, 0.1], [[0, 0, 0, 1], [0, 0, 0, 0]], "zero length"),
        ([0.0], None, r"need N times"),
    ],
)
def test_a_bad_track_is_refused(times, quaternions, match: str) -> None:
    q = np.array(quaternions if quaternions is not None else [[0, 0, 0, 1], [0, 0, 0, 1]], dtype=float)
    with pytest.raises(ScanError, match=match):
        PoseTrack(np.array(times), np.zeros((2, 3)), q)
