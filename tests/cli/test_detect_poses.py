"""``negobs detect --poses``: fusion follows a moving vehicle on recorded frames.

The recording is synthetic (.bin files of an analytic HDL-64-like scan): a 3 x 1.5 m pit 12 m
ahead, approached 1 m per frame, so the pit is 12, 11, 10, 9 m ahead in the four frames.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from negobs_gym.cli import main
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.loaders import sensor_to_ros_frame
from negobs_gym.detector.synthetic import HDL64_ELEVATION_DEG, Hole, hdl64_scan, synthetic_scan

NEAR_M, LENGTH_M, STEP_M, FRAMES = 12.0, 1.5, 1.0, 4
RING_GAP_M = 0.6  # a pair's A is the last ground return before the pit: up to a ring gap early


@pytest.fixture(scope="module")
def drive(tmp_path_factory) -> tuple[list[str], Path]:
    """The frames as .bin files (ROS sensor frame, x, y, z, intensity, ring) and a poses CSV."""
    folder = tmp_path_factory.mktemp("drive")
    files = []
    for k in range(FRAMES):
        files.append(_write_bin(hdl64_scan([_pit(k)]), folder / f"f{k}.bin"))
    poses = folder / "poses.csv"
    rows = [f"{k * 0.1:.1f},{k * STEP_M},0,0,0,0,0" for k in range(FRAMES)]
    poses.write_text("timestamp,x,y,z,roll,pitch,yaw\n" + "\n".join(rows) + "\n")
    return files, poses


def _pit(frame: int) -> Hole:
    """The pit in the vehicle frame at ``frame``: NEAR_M ahead at the first, STEP_M nearer each."""
    near = NEAR_M - frame * STEP_M
    return Hole(x0_m=-1.5, x1_m=1.5, y0_m=near, y1_m=near + LENGTH_M, depth_m=1.0)


def _write_bin(scan: StructuredScan, path: Path) -> str:
    """``scan``'s returns as a .bin file in the ROS sensor frame (x, y, z, intensity, ring)."""
    valid = scan.valid
    p = scan.points_sensor[valid]  # X right, Y forward -> ROS x forward, y left
    ring = np.broadcast_to(np.arange(scan.shape[0])[:, None], scan.shape)[valid]
    np.column_stack([sensor_to_ros_frame(p), np.zeros(len(p)), ring]).astype(np.float32).tofile(path)
    return str(path)


def _records(files: list[str], out: Path, *extra: str) -> list[dict]:
    args = ["-q", "detect", *files, "--bin-fields", "xyzir", "--height", "2.2", "--no-png", "--out", str(out)]
    assert main([*args, *extra]) == 0
    return [json.loads((out / f"{k:05d}_f{k}_0000.json").read_text()) for k in range(FRAMES)]


def _near_edges(record: dict) -> list[float]:
    return [min(y for _, y in ob["outline_xy_m"]) for ob in record["obstacles"]]


@pytest.fixture(scope="module")
def csv_records(drive, tmp_path_factory) -> list[dict]:
    """The drive's records with the poses CSV: the run every other pose source is compared with."""
    files, poses = drive
    return _records(files, tmp_path_factory.mktemp("csv"), "--poses", str(poses))


def _assert_csv_poses_and_outlines(records: list[dict], from_csv: list[dict], atol: float) -> None:
    """``records`` hold the CSV drive's poses (to ``atol``) and outlines (to 1 mm)."""
    for record, csv_record in zip(records, from_csv, strict=True):
        np.testing.assert_allclose(record["pose"], csv_record["pose"], atol=atol)
        np.testing.assert_allclose(_near_edges(record), _near_edges(csv_record), atol=1e-3)


def test_poses_keep_the_pit_where_it_is_and_standing_still_loses_it(drive, csv_records, tmp_path) -> None:
    files, _ = drive
    moving = csv_records
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


def test_tightened_pairs_and_short_poses(drive, csv_records, tmp_path, capsys) -> None:
    files, poses = drive
    moving = csv_records
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


START_NS, PERIOD_NS = 10**9, 10**8  # clouds at 10 Hz from t = 1 s
# the recorder receives clouds 30 ms and poses 5 ms after their header stamps
CLOUD_LATENCY_NS, POSE_LATENCY_NS = 30 * 10**6, 5 * 10**6
POSE_STAMPS_NS = [START_NS + j * PERIOD_NS // 5 for j in range(-2, 5 * (FRAMES - 1) + 3)]  # 50 Hz
MAP_ODOM = (np.array([5.0, 0.0, 0.0]), Rotation.from_euler("z", 90, degrees=True))  # a localiser's


def _stamp(store, stamp_ns: int):
    return store.types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)


def _drive_bag(bag: Path, files: list[str], write_poses) -> Path:
    """The drive's clouds as a ROS 2 bag on /points, and what ``write_poses(writer, store)`` adds."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from tests.helpers import pointcloud2

    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(bag, version=9) as writer:
        clouds = writer.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=store)
        for k, path in enumerate(files):
            raw = np.fromfile(path, dtype=np.float32).reshape(-1, 5)
            points = np.zeros(
                len(raw), dtype=[(n, "<f4") for n in "xyz"] + [("intensity", "<f4"), ("ring", "<u2")]
            )
            for i, name in enumerate(("x", "y", "z", "intensity", "ring")):
                points[name] = raw[:, i]
            stamp = START_NS + k * PERIOD_NS
            msg = pointcloud2(store, points, stamp)
            writer.write(
                clouds, stamp + CLOUD_LATENCY_NS, store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")
            )
        write_poses(writer, store)
    return bag


def _driven_x(stamp_ns: int) -> float:
    """Where the drive is at ``stamp_ns``: 1 m per cloud period, as the CSV's poses."""
    return STEP_M * (stamp_ns - START_NS) / PERIOD_NS


def test_a_bag_takes_its_poses_from_its_odometry_topic(drive, csv_records, tmp_path, capsys) -> None:
    files, _ = drive

    def odometry(writer, store) -> None:
        from tests.helpers import odometry as odometry_msg

        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        for stamp in POSE_STAMPS_NS:
            msg = store.serialize_cdr(odometry_msg(store, stamp, _driven_x(stamp)), "nav_msgs/msg/Odometry")
            writer.write(odom, stamp + POSE_LATENCY_NS, msg)

    bag = _drive_bag(tmp_path / "drive_ros2", files, odometry)
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
    _assert_csv_poses_and_outlines(from_bag, csv_records, atol=1e-9)
    assert len(_near_edges(from_bag[3])) == 1
    assert main([*args[1:-2], "--out", str(tmp_path / "x"), "--poses-topic", "/imu"]) == 2
    assert "no topic '/imu'" in capsys.readouterr().err
    assert main(["detect", files[0], "--out", str(tmp_path / "y"), "--poses-topic", "/odom"]) == 2
    assert "not a readable ROS bag" in capsys.readouterr().err


def _write_tf_tree(
    writer, store, mount, map_odom, *, localiser: bool = False, sensor_frame: str = "velodyne"
) -> None:
    """The drive as a tf tree: ``map -> odom`` (static, or with ``localiser`` one 1 Hz correction
    on /tf at the first cloud), ``odom -> base_link`` at 50 Hz on /tf, and the mounting
    ``base_link -> sensor_frame`` (position, Rotation; ROS axes) on /tf_static."""
    t = store.types

    def stamped(stamp_ns: int, parent: str, child: str, position, rotation):
        x, y, z = (float(v) for v in position)
        qx, qy, qz, qw = (float(v) for v in rotation.as_quat())
        return t["geometry_msgs/msg/TransformStamped"](
            header=t["std_msgs/msg/Header"](stamp=_stamp(store, stamp_ns), frame_id=parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
                rotation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
            ),
        )

    def write(connection, record_ns: int, transforms) -> None:
        msg = t["tf2_msgs/msg/TFMessage"](transforms=transforms)
        writer.write(connection, record_ns, store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))

    static = writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=store)
    dynamic = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
    write(static, START_NS - PERIOD_NS, [stamped(0, "base_link", sensor_frame, *mount)])
    if not localiser:
        write(static, START_NS - PERIOD_NS, [stamped(0, "map", "odom", *map_odom)])
    else:
        write(dynamic, START_NS + POSE_LATENCY_NS, [stamped(START_NS, "map", "odom", *map_odom)])
    to_odom = map_odom[1].inv()
    for stamp in POSE_STAMPS_NS:  # odom -> base_link = (map -> odom)^-1 * (the CSV's pose in map)
        position = to_odom.apply(np.array([_driven_x(stamp), 0.0, 0.0]) - map_odom[0])
        write(dynamic, stamp + POSE_LATENCY_NS, [stamped(stamp, "odom", "base_link", position, to_odom)])


def test_a_bag_takes_its_poses_from_its_tf_tree(drive, csv_records, tmp_path, capsys) -> None:
    """The drive's poses as a tf tree: a localiser's static map -> odom (5 m off, turned 90 deg),
    wheel odometry odom -> base_link at 50 Hz on /tf, the sensor's mounting below base_link; the
    chain map -> base_link gives the CSV's poses and outlines."""
    files, _ = drive

    def tf_tree(writer, store, localiser: bool = False, mount_pitch_deg: float = 0.0) -> None:
        mount = (np.array([0.0, 0.0, 2.2]), Rotation.from_euler("y", mount_pitch_deg, degrees=True))
        _write_tf_tree(writer, store, mount, MAP_ODOM, localiser=localiser)

    bag = _drive_bag(tmp_path / "tf_ros2", files, tf_tree)
    out = tmp_path / "bag"
    args = ["-q", "detect", str(bag), "--height", "2.2", "--no-png", "--stamps", "header"]
    assert main([*args, "--out", str(out), "--tf", "map:base_link"]) == 0
    assert "deg from the --sensor" not in capsys.readouterr().err  # mounted as --sensor says
    from_tf = [json.loads((out / f"{k:05d}_tf_ros2_{k:04d}.json").read_text()) for k in range(FRAMES)]
    _assert_csv_poses_and_outlines(from_tf, csv_records, atol=1e-9)
    from_csv = csv_records
    # odom -> base_link alone: the drive as odometry saw it, 5 m off and turned against the map
    assert main([*args, "--out", str(tmp_path / "odom"), "--tf", "odom:base_link"]) == 0
    odom = json.loads((tmp_path / "odom" / "00001_tf_ros2_0001.json").read_text())
    assert abs(odom["pose"][5]) == pytest.approx(np.pi)  # facing odom's -y: this package's yaw +-pi
    assert main([*args, "--out", str(tmp_path / "x"), "--tf", "map:lidar"]) == 2
    assert "no frame 'lidar'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main([*args, "--out", str(tmp_path / "y"), "--tf", "base_link"])
    assert exit_info.value.code == 2
    assert "want two frame names FIXED:BODY" in capsys.readouterr().err
    # a localiser's 1 Hz map -> odom on /tf: its one correction lies 0.2 s before the third cloud
    slow = _drive_bag(
        tmp_path / "slow_ros2", files, lambda writer, store: tf_tree(writer, store, localiser=True)
    )
    slow_args = ["-q", "detect", str(slow), "--height", "2.2", "--no-png", "--stamps", "header"]
    assert main([*slow_args, "--out", str(tmp_path / "s"), "--tf", "map:base_link"]) == 2
    assert "frame 2: tf map -> odom: no pose at t = 1.200 s" in capsys.readouterr().err
    one_s = ["--max-pose-gap", "1", "--out", str(tmp_path / "s1"), "--tf", "map:base_link"]
    assert main([*slow_args, *one_s]) == 0
    last = json.loads((tmp_path / "s1" / f"{FRAMES - 1:05d}_slow_ros2_{FRAMES - 1:04d}.json").read_text())
    np.testing.assert_allclose(last["pose"], from_csv[-1]["pose"], atol=1e-9)
    # a sensor the tf pitches 3 deg down on the vehicle, where --sensor hdl64 assumes it upright:
    # the detector's ground would be off, and the run says so (the upright one above did not)
    pitched = _drive_bag(tmp_path / "pitched", files, lambda w, st: tf_tree(w, st, mount_pitch_deg=3.0))
    capsys.readouterr()
    assert (
        main(["-q", "detect", str(pitched), *args[3:], "--out", str(tmp_path / "p"), "--tf", "map:base_link"])
        == 0
    )
    warned = [line for line in capsys.readouterr().err.splitlines() if "deg from the --sensor" in line]
    assert len(warned) == 1 and "(base_link -> velodyne) turns the cloud's frame 3.0 deg" in warned[0]
    no_tf = _drive_bag(tmp_path / "points_only", files, lambda writer, store: None)
    assert main(["detect", str(no_tf), "--out", str(tmp_path / "z"), "--tf", "odom:base_link"]) == 2
    assert "no tf topic" in capsys.readouterr().err


def test_mount_from_tf_puts_the_sensor_where_the_tree_mounts_it(drive, csv_records, tmp_path, capsys) -> None:
    """The roof sensor 1 m ahead of base_link and 1.5 m above it, pitched 3 deg nose down, with
    base_link 0.4 m above the ground: ``--mount-from-tf --body-height 0.4`` reads it where it is
    and finds the pit where it is; ``--sensor``'s upright mounting at the vehicle origin does not."""
    files, _ = drive
    pitched = Rotation.from_euler("x", -3, degrees=True).as_matrix()  # this package's axes: nose down
    azimuth = np.linspace(-np.pi, np.pi, 4000, endpoint=False)
    elevation = np.radians(np.sort(HDL64_ELEVATION_DEG))
    mounted = [
        _write_bin(
            synthetic_scan("hdl64", elevation, azimuth, pitched, np.array([0.0, 1.0, 1.9]), [_pit(k)]),
            tmp_path / f"m{k}.bin",
        )
        for k in range(FRAMES)
    ]
    mount = (np.array([1.0, 0.0, 1.5]), Rotation.from_euler("y", 3, degrees=True))  # ROS: x forward
    bag = _drive_bag(tmp_path / "mounted", mounted, lambda w, st: _write_tf_tree(w, st, mount, MAP_ODOM))
    args = ["-q", "detect", str(bag), "--no-png", "--stamps", "header", "--tf", "map:base_link"]

    def records(out: str, *extra: str) -> list[dict]:
        assert main([*args, "--out", str(tmp_path / out), *extra]) == 0
        return [
            json.loads((tmp_path / out / f"{k:05d}_mounted_{k:04d}.json").read_text()) for k in range(FRAMES)
        ]

    from_tf = records("tf", "--mount-from-tf", "--body-height", "0.4")
    assert "deg from the --sensor" not in capsys.readouterr().err
    assert from_tf[0]["height_m"] == pytest.approx(1.9)
    np.testing.assert_allclose(from_tf[0]["mounting"]["translation_m"], [0.0, 1.0, 1.9], atol=1e-9)
    forward = np.asarray(from_tf[0]["mounting"]["rotation"]) @ [0.0, 1.0, 0.0]  # the sensor's +Y
    np.testing.assert_allclose(forward, [0.0, np.cos(np.radians(3)), -np.sin(np.radians(3))], atol=1e-9)
    # the vehicle's pose is base_link's 0.4 m lower: the CSV's, z = -0.4
    csv_poses = [r["pose"] for r in csv_records]
    np.testing.assert_allclose(
        [r["pose"] for r in from_tf], np.add(csv_poses, [0, 0, -0.4, 0, 0, 0]), atol=1e-9
    )
    assumed = records("assumed", "--height", "1.9")  # the --sensor mounting: upright at the origin
    assert "turns the cloud's frame 3.0 deg from the --sensor hdl64" in capsys.readouterr().err
    for k in (2, 3):
        near = NEAR_M - k * STEP_M
        (edge,) = _near_edges(from_tf[k])
        assert near - RING_GAP_M <= edge <= near + LENGTH_M, (k, edge)
        assert all(e < near - RING_GAP_M for e in _near_edges(assumed[k])), (k, _near_edges(assumed[k]))
    # the options' own rules, and a tree that does not mount the clouds' frame
    assert main([*args, "--out", str(tmp_path / "bad"), "--height", "1.9", "--mount-from-tf"]) == 2
    assert "--height and --mount-from-tf" in capsys.readouterr().err
    assert main(["detect", *files, "--out", str(tmp_path / "bad"), "--body-height", "0.4"]) == 2
    assert "go with --tf FIXED:BODY" in capsys.readouterr().err
    imu_only = _drive_bag(
        tmp_path / "imu_only",
        mounted,
        lambda w, st: _write_tf_tree(w, st, mount, MAP_ODOM, sensor_frame="imu"),
    )
    assert main([*args[:2], str(imu_only), *args[3:], "--out", str(tmp_path / "bad"), "--mount-from-tf"]) == 2
    assert "--mount-from-tf: " in (err := capsys.readouterr().err) and "no frame 'velodyne'" in err
    # a tf that rolls the sensor 90 deg (a side mount) read through --sensor hdl64's upright path
    rolled = (mount[0], Rotation.from_euler("x", 90, degrees=True))
    side = _drive_bag(tmp_path / "side", mounted[:1], lambda w, st: _write_tf_tree(w, st, rolled, MAP_ODOM))
    assert (
        main([*args[:2], str(side), *args[3:], "--out", str(tmp_path / "side_out"), "--mount-from-tf"]) == 0
    )
    assert "turns the cloud's frame 90.0 deg from the --sensor hdl64 mounting" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["odometry", "raw"])
def test_kitti_files_give_the_csvs_vehicle_poses(kind, drive, csv_records, tmp_path, capsys) -> None:
    """The same drive as a KITTI odometry sequence (camera poses and a calib.txt whose Tr is
    sequence 00's) or a KITTI raw drive (OXTS fixes at Karlsruhe and 2011_09_26's IMU-to-Velodyne
    calibration): the vehicle's poses and the outlines equal those of the CSV (whose first pose is
    the origin, as the OXTS poses' is)."""
    import argparse

    from negobs_gym.cli.detect_sensors import scan_setup
    from negobs_gym.detector.io import read_poses_csv
    from tests.detector.io.test_kitti import (
        IMU_TO_VELO_0926,
        TR_00,
        _camera_poses,
        _write,
        oxts_fixes,
        write_imu_to_velo,
        write_oxts,
    )

    files, poses = drive
    setup = scan_setup(argparse.Namespace(sensor="hdl64", height=2.2, azimuth_resolution=None, mount=None))
    vehicles, calib = read_poses_csv(poses), tmp_path / "calib.txt"
    if kind == "odometry":
        option, given = "--kitti-poses", tmp_path / "00.txt"
        _write(given, _camera_poses(vehicles, TR_00, setup))
        calib.write_text("Tr: " + " ".join(map(str, TR_00.ravel())) + "\n")
    else:
        option, given = "--kitti-oxts", tmp_path / "oxts"
        write_oxts(given, oxts_fixes(vehicles, IMU_TO_VELO_0926, setup))
        write_imu_to_velo(calib, IMU_TO_VELO_0926)
    records = _records(files, tmp_path / "kitti", option, str(given), "--kitti-calib", str(calib))
    _assert_csv_poses_and_outlines(records, csv_records, atol=1e-6)
    assert main(["detect", files[0], "--out", str(tmp_path / "x"), option, str(given)]) == 2
    assert "--kitti-calib goes with --kitti-poses" in capsys.readouterr().err


def test_a_timed_poses_csv_is_read_at_each_clouds_time(drive, csv_records, tmp_path, capsys) -> None:
    """An INS log (timestamp, pose) beside the bag's clouds gives what its odometry topic gives."""
    files, poses = drive
    bag = _drive_bag(tmp_path / "log_ros2", files, lambda writer, store: None)
    log = tmp_path / "ins.csv"
    rows = [f"{stamp * 1e-9:.6f},{_driven_x(stamp):.6f},0,0,0,0,0" for stamp in reversed(POSE_STAMPS_NS)]
    log.write_text("timestamp,x,y,z,roll,pitch,yaw\n" + "\n".join(rows) + "\n")  # in any order
    out = tmp_path / "track"
    args = ["-q", "detect", str(bag), "--height", "2.2", "--no-png", "--stamps", "header"]
    assert main([*args, "--out", str(out), "--poses-track", str(log)]) == 0
    records = [json.loads((out / f"{k:05d}_log_ros2_{k:04d}.json").read_text()) for k in range(FRAMES)]
    _assert_csv_poses_and_outlines(records, csv_records, atol=1e-6)
    # a log on another clock (the frames' CSV: 0-0.3 s), without times, or with two poses at one
    # time is refused by name
    assert main([*args, "--out", str(tmp_path / "x"), "--poses-track", str(poses)]) == 2
    assert "frame 0: no pose at t = 1.000 s: the poses span 0.000-0.300 s" in capsys.readouterr().err
    untimed = tmp_path / "untimed.csv"
    untimed.write_text("x,y,z,roll,pitch,yaw\n0,0,0,0,0,0\n")
    assert main([*args, "--out", str(tmp_path / "z"), "--poses-track", str(untimed)]) == 2
    assert "missing pose columns ['timestamp']" in capsys.readouterr().err
    assert main(["detect", *files, "--out", str(tmp_path / "b"), "--poses-track", str(log)]) == 2
    assert "its frames carry no time, which --poses-track needs" in capsys.readouterr().err
    twice = tmp_path / "twice.csv"
    twice.write_text("timestamp,x,y,z,roll,pitch,yaw\n1.0,0,0,0,0,0,0\n1.0,1,0,0,0,0,0\n")
    assert main([*args, "--out", str(tmp_path / "y"), "--poses-track", str(twice)]) == 2
    assert "times must increase strictly" in capsys.readouterr().err
