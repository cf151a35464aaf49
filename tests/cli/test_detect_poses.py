"""``negobs detect --poses``: fusion follows a moving vehicle on recorded frames.

The recording is synthetic (.bin files of an analytic HDL-64-like scan): a 3 x 1.5 m pit 12 m
ahead, approached 1 m per frame, so the pit is 12, 11, 10, 9 m ahead in the four frames.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.detector.synthetic import Hole, hdl64_scan

NEAR_M, LENGTH_M, STEP_M, FRAMES = 12.0, 1.5, 1.0, 4
RING_GAP_M = 0.6  # a pair's A is the last ground return before the pit: up to a ring gap early


@pytest.fixture(scope="module")
def drive(tmp_path_factory) -> tuple[list[str], Path]:
    """The frames as .bin files (ROS sensor frame, x, y, z, intensity, ring) and a poses CSV."""
    folder = tmp_path_factory.mktemp("drive")
    files = []
    for k in range(FRAMES):
        near = NEAR_M - k * STEP_M
        scan = hdl64_scan([Hole(x0_m=-1.5, x1_m=1.5, y0_m=near, y1_m=near + LENGTH_M, depth_m=1.0)])
        valid = scan.valid
        p = scan.points_sensor[valid]  # X right, Y forward -> ROS x forward, y left
        ring = np.broadcast_to(np.arange(scan.shape[0])[:, None], scan.shape)[valid]
        cloud = np.column_stack([p[:, 1], -p[:, 0], p[:, 2], np.zeros(len(p)), ring]).astype(np.float32)
        path = folder / f"f{k}.bin"
        cloud.tofile(path)
        files.append(str(path))
    poses = folder / "poses.csv"
    rows = [f"{k * 0.1:.1f},{k * STEP_M},0,0,0,0,0" for k in range(FRAMES)]
    poses.write_text("timestamp,x,y,z,roll,pitch,yaw\n" + "\n".join(rows) + "\n")
    return files, poses


def _records(files: list[str], out: Path, *extra: str) -> list[dict]:
    args = ["-q", "detect", *files, "--bin-fields", "xyzir", "--height", "2.2", "--no-png", "--out", str(out)]
    assert main([*args, *extra]) == 0
    return [json.loads((out / f"{k:05d}_f{k}_0000.json").read_text()) for k in range(FRAMES)]


def _near_edges(record: dict) -> list[float]:
    return [min(y for _, y in ob["outline_xy_m"]) for ob in record["obstacles"]]


def test_poses_keep_the_pit_where_it_is_and_standing_still_loses_it(drive, tmp_path) -> None:
    files, poses = drive
    moving = _records(files, tmp_path / "moving", "--poses", str(poses))
    standing = _records(files, tmp_path / "standing")
    for k in (2, 3):  # confirmed after three frames (paper N §4.2), then kept on the pit as it nears
        near = NEAR_M - k * STEP_M
        (edge,) = _near_edges(moving[k])
        assert near - RING_GAP_M <= edge <= near + LENGTH_M, (k, edge)
    # recorded as this package's pose: the same world x, the car facing world +x at yaw -90 deg
    assert [r["pose"][0] for r in moving] == [k * STEP_M for k in range(FRAMES)]
    assert all(r["pose"][5] == pytest.approx(-np.pi / 2) for r in moving)
    assert standing[0]["pose"] is None
    # taken as standing still, the frames' pairs do not line up: the pit is drawn where the first
    # frame saw it, then lost
    assert all(edge > NEAR_M - 2 * STEP_M + LENGTH_M for edge in _near_edges(standing[2]))
    assert standing[3]["n_obstacles"] == 0


def test_tightened_pairs_and_short_poses(drive, tmp_path, capsys) -> None:
    files, poses = drive
    moving = _records(files, tmp_path / "moving", "--poses", str(poses))
    tight = _records(files, tmp_path / "tight", "--poses", str(poses), "--tighten-pairs")
    near = NEAR_M - 3 * STEP_M
    (edge,), (kept,) = _near_edges(tight[3]), _near_edges(moving[3])
    assert near - RING_GAP_M <= edge <= near + LENGTH_M
    assert edge > kept + 0.2  # the near edge moved to the closer frames' last ground return (~0.1 m)
    short = tmp_path / "short.csv"
    short.write_text("\n".join(poses.read_text().splitlines()[:3]) + "\n")  # two poses, four frames
    args = ["detect", *files, "--bin-fields", "xyzir", "--no-png", "--out", str(tmp_path / "s")]
    assert main([*args, "--poses", str(short)]) == 2
    assert "2 poses, but the recording has more frames" in capsys.readouterr().err


def test_a_bag_takes_its_poses_from_its_odometry_topic(drive, tmp_path, capsys) -> None:
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from tests.helpers import pointcloud2

    files, poses = drive
    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    bag = tmp_path / "drive_ros2"
    start_ns, period_ns = 10**9, 10**8  # clouds at 10 Hz, odometry at 50 Hz around them
    # the recorder receives clouds 30 ms and odometry 5 ms after their header stamps
    cloud_latency_ns, odom_latency_ns = 30 * 10**6, 5 * 10**6
    with Writer(bag, version=9) as writer:
        clouds = writer.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=store)
        for k, path in enumerate(files):
            raw = np.fromfile(path, dtype=np.float32).reshape(-1, 5)
            points = np.zeros(
                len(raw), dtype=[(n, "<f4") for n in "xyz"] + [("intensity", "<f4"), ("ring", "<u2")]
            )
            for i, name in enumerate(("x", "y", "z", "intensity", "ring")):
                points[name] = raw[:, i]
            stamp = start_ns + k * period_ns
            msg = pointcloud2(store, points, stamp)
            writer.write(
                clouds, stamp + cloud_latency_ns, store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")
            )
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        for j in range(-2, 5 * (FRAMES - 1) + 3):
            stamp = start_ns + j * period_ns // 5
            x = STEP_M * j / 5  # 1 m per cloud period, as the CSV's poses
            pose = t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
                orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            )
            zero = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
            msg = t["nav_msgs/msg/Odometry"](
                header=t["std_msgs/msg/Header"](
                    stamp=t["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9),
                    frame_id="odom",
                ),
                child_frame_id="base_link",
                pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=t["geometry_msgs/msg/TwistWithCovariance"](
                    twist=t["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
                ),
            )
            writer.write(odom, stamp + odom_latency_ns, store.serialize_cdr(msg, "nav_msgs/msg/Odometry"))
    out = tmp_path / "bag"
    args = ["-q", "detect", str(bag), "--topic", "/points", "--height", "2.2", "--no-png", "--out", str(out)]
    # timed by the bag's record time each cloud takes the pose 25 ms later: 0.25 m ahead at 10 m/s
    assert main([*args[:-1], str(tmp_path / "record"), "--poses-topic", "/odom"]) == 0
    recorded = [
        json.loads((tmp_path / "record" / f"{k:05d}_drive_ros2_{k:04d}.json").read_text()) for k in range(2)
    ]
    assert [r["pose"][0] for r in recorded] == pytest.approx([0.25, STEP_M + 0.25])
    assert main([*args, "--poses-topic", "/odom", "--stamps", "header"]) == 0
    from_bag = [json.loads((out / f"{k:05d}_drive_ros2_{k:04d}.json").read_text()) for k in range(FRAMES)]
    from_csv = _records(files, tmp_path / "csv", "--poses", str(poses))
    for bag_record, csv_record in zip(from_bag, from_csv, strict=True):
        np.testing.assert_allclose(bag_record["pose"], csv_record["pose"], atol=1e-9)
        np.testing.assert_allclose(_near_edges(bag_record), _near_edges(csv_record), atol=1e-3)
    assert len(_near_edges(from_bag[3])) == 1
    assert main([*args[1:-2], "--out", str(tmp_path / "x"), "--poses-topic", "/imu"]) == 2
    assert "no topic '/imu'" in capsys.readouterr().err
    assert main(["detect", files[0], "--out", str(tmp_path / "y"), "--poses-topic", "/odom"]) == 2
    assert "not a readable ROS bag" in capsys.readouterr().err


def test_kitti_poses_give_the_csvs_vehicle_poses(drive, tmp_path, capsys) -> None:
    """The same drive as a KITTI sequence: camera poses and a calib.txt whose Tr is sequence 00's;
    the vehicle's poses, the outlines and the poses recorded equal those of the CSV."""
    import argparse

    from negobs_gym.cli.detect import scan_setup
    from negobs_gym.detector.io import read_poses_csv
    from tests.detector.io.test_kitti import TR_00, _camera_poses, _write

    files, poses = drive
    setup = scan_setup(argparse.Namespace(sensor="hdl64", height=2.2, azimuth_resolution=None))
    _write(tmp_path / "00.txt", _camera_poses(read_poses_csv(poses), TR_00, setup))
    calib = tmp_path / "calib.txt"
    calib.write_text("Tr: " + " ".join(map(str, TR_00.ravel())) + "\n")
    kitti = _records(
        files, tmp_path / "kitti", "--kitti-poses", str(tmp_path / "00.txt"), "--kitti-calib", str(calib)
    )
    from_csv = _records(files, tmp_path / "csv", "--poses", str(poses))
    for k_record, csv_record in zip(kitti, from_csv, strict=True):
        np.testing.assert_allclose(k_record["pose"], csv_record["pose"], atol=1e-6)
        np.testing.assert_allclose(_near_edges(k_record), _near_edges(csv_record), atol=1e-3)
    args = ["detect", files[0], "--out", str(tmp_path / "x"), "--kitti-poses", str(tmp_path / "00.txt")]
    assert main(args) == 2
    assert "--kitti-poses and --kitti-calib go together" in capsys.readouterr().err
