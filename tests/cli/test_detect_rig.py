"""``negobs detect --cloud``: paper N's rig (a top HDL-64, two side HDL-32s rolled 90 deg), each
LiDAR on its own topic and clock, in one detector update.

The bag is synthetic: each sensor at its paper N rig mount scans a 1 x 1 m pit, 0.8 m deep, that
the vehicle approaches at 25 km/h (7 m/s); the top sensor's clouds at 10 Hz, the left's 40 ms
earlier and the right's 30 ms later (sensors that are not phase-locked), odometry at 50 Hz.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from negobs_gym.cli import main
from negobs_gym.detector.io.setup import PACKAGE_TO_ROS_BODY
from negobs_gym.detector.synthetic import HDL32_ELEVATION_DEG, HDL64_ELEVATION_DEG, Hole, synthetic_scan
from negobs_gym.sensors.rigs import paper_n_rig
from tests.helpers import odometry, pointcloud2, ros_ring_cloud

SPEED_MPS, NEAR_M, FRAMES = 7.0, 8.5, 4  # the pit 8.5, 7.8, 7.1, 6.4 m ahead at the top's clouds
START_NS, PERIOD_NS = 10**9, 10**8
# topic -> (rig mount, --sensor, clock offset from the top sensor's [ns])
RIG = {
    "/top": ("hdl64", "hdl64", 0),
    "/left": ("hdl32_left", "hdl32-left", -40 * 10**6),
    "/right": ("hdl32_right", "hdl32-right", 30 * 10**6),
}
CLOUDS = [arg for topic, (_, sensor, _) in RIG.items() for arg in ("--cloud", f"{topic}:{sensor}")]
A_BEFORE_M = 0.2  # a pair's A, the last ground return before the pit: up to a ring gap before it


def _near(time_s: float) -> float:
    """The pit's near edge ahead of the vehicle at ``time_s`` after the first cloud."""
    return NEAR_M - SPEED_MPS * time_s


def _mount(name: str):
    return next(m for m in paper_n_rig().mounts if m.name == name)


def _ros_rotation(mount) -> np.ndarray:
    """The mount's rotation from its ROS sensor axes (x forward) to ROS body axes."""
    return PACKAGE_TO_ROS_BODY @ mount.rotation_matrix @ PACKAGE_TO_ROS_BODY.T


def _tf_message(store, transforms) -> bytes:
    """A serialised tf2_msgs/TFMessage of ``(stamp_ns, parent, child, position, rotation matrix)``."""
    t = store.types
    stamped = []
    for stamp_ns, parent, child, position, rotation in transforms:
        (x, y, z), (qx, qy, qz, qw) = position, Rotation.from_matrix(rotation).as_quat()
        stamp = t["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
        stamped.append(
            t["geometry_msgs/msg/TransformStamped"](
                header=t["std_msgs/msg/Header"](stamp=stamp, frame_id=parent),
                child_frame_id=child,
                transform=t["geometry_msgs/msg/Transform"](
                    translation=t["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z)),
                    rotation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
                ),
            )
        )
    msg = t["tf2_msgs/msg/TFMessage"](transforms=stamped)
    return store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage")


def _cloud(mount: str, time_s: float) -> np.ndarray:
    """The returns of the rig's ``mount`` at ``time_s``, in its ROS frame, with their ring."""
    sensor = _mount(mount)
    elevation = HDL64_ELEVATION_DEG if mount == "hdl64" else HDL32_ELEVATION_DEG
    n = 4000 if mount == "hdl64" else 2250  # 0.09 and 0.16 deg columns
    # mid-column azimuths: float32 coordinates on a column's edge would fall either side of it
    azimuth = np.linspace(-np.pi, np.pi, n, endpoint=False) + np.pi / n
    hole = Hole.ahead(_near(time_s), 1.0, 1.0, 0.8)
    scan = synthetic_scan(
        mount, np.radians(elevation), azimuth, sensor.rotation_matrix, np.array(sensor.translation_m), [hole]
    )
    return ros_ring_cloud(scan)


@pytest.fixture(scope="module")
def rig_bag(tmp_path_factory) -> Path:
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    bag = tmp_path_factory.mktemp("rig") / "rig"
    messages = []
    with Writer(bag, version=9) as writer:
        for topic, (mount, _, offset_ns) in RIG.items():
            connection = writer.add_connection(topic, "sensor_msgs/msg/PointCloud2", typestore=store)
            for k in range(FRAMES):
                stamp = START_NS + k * PERIOD_NS + offset_ns
                cloud = _cloud(mount, (stamp - START_NS) * 1e-9)
                msg = pointcloud2(store, cloud, stamp, frame_id=topic.strip("/"))
                messages.append((stamp, connection, store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")))
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        for j in range(-5, 5 * FRAMES + 5):
            stamp = START_NS + j * PERIOD_NS // 5
            x = SPEED_MPS * (stamp - START_NS) * 1e-9
            messages.append(
                (stamp, odom, store.serialize_cdr(odometry(store, stamp, x), "nav_msgs/msg/Odometry"))
            )
            moved = _tf_message(store, [(stamp, "odom", "base_link", np.array([x, 0.0, 0.0]), np.eye(3))])
            messages.append((stamp, tf, moved))
        # each LiDAR's mounting below base_link (on the ground), in ROS axes, under its cloud's frame_id
        static = writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=store)
        mounts = [
            (0, "base_link", topic.strip("/"), PACKAGE_TO_ROS_BODY @ m.translation_m, _ros_rotation(m))
            for topic, m in ((t, _mount(mount)) for t, (mount, _, _) in RIG.items())
        ]
        messages.append((START_NS - PERIOD_NS, static, _tf_message(store, mounts)))
        for stamp, connection, raw in sorted(messages, key=lambda m: m[0]):
            writer.write(connection, stamp, raw)
    return bag


def _records(bag: Path, out: Path, *extra: str) -> list[dict]:
    assert main(["-q", "detect", str(bag), "--no-png", "--out", str(out), *extra]) == 0
    return [json.loads((out / f"{k:05d}_rig_{k:04d}.json").read_text()) for k in range(FRAMES)]


def _a_ahead(record: dict, sensor: str) -> np.ndarray:
    """How far ahead this frame's pairs of ``sensor`` put their A points [m]."""
    return np.array(record["frame_pairs"][sensor]["a_m"])[:, 1]


def test_the_rig_finds_the_pit_in_one_update_with_each_cloud_at_the_lead_time(rig_bag, tmp_path) -> None:
    records = _records(rig_bag, tmp_path / "rig", *CLOUDS, "--poses-topic", "/odom")
    for k, record in enumerate(records):
        near = _near(k * PERIOD_NS * 1e-9)
        assert [(c["topic"], c["input"], c["frame"]) for c in record["clouds"]] == [
            ("/top", "hdl64", k),
            ("/left", "hdl32_left", k),
            ("/right", "hdl32_right", k),
        ]
        assert [c["dt_s"] for c in record["clouds"]] == pytest.approx([0.0, -0.04, 0.03])
        # each sensor's pairs on the pit's near edge as the vehicle sees it at the top's cloud
        for sensor in ("hdl64", "hdl32_left", "hdl32_right"):
            a = _a_ahead(record, sensor)
            assert a.size and np.all((a > near - A_BEFORE_M) & (a < near + 0.1)), (k, sensor, a)
        # three sensors seeing a new pit confirm it in one frame (paper N §4.2)
        (obstacle,) = record["obstacles"]
        assert near - A_BEFORE_M < min(y for _, y in obstacle["outline_xy_m"]) <= near
    # the left cloud is 40 ms old: the vehicle was 0.28 m behind; the mounting stays as recorded
    lead, left = records[0]["clouds"][:2]
    np.testing.assert_allclose(left["mounting"]["translation_m"], [-0.9, 0.5, 2.0], atol=1e-6)
    np.testing.assert_allclose(left["motion"]["translation_m"], [0.0, -SPEED_MPS * 0.04, 0.0], atol=1e-6)
    np.testing.assert_allclose(left["motion"]["rotation"], np.eye(3), atol=1e-9)
    np.testing.assert_allclose(lead["motion"]["translation_m"], [0.0, 0.0, 0.0], atol=1e-12)
    assert json.loads((tmp_path / "rig" / "summary.json").read_text())[0]["n_clouds"] == 3


def test_without_timed_poses_each_cloud_lies_where_the_vehicle_was_at_its_own_time(
    rig_bag, tmp_path, capsys
) -> None:
    still = _records(rig_bag, tmp_path / "still", *CLOUDS)  # no poses: standing still
    for k, record in enumerate(still):
        near = _near(k * PERIOD_NS * 1e-9)
        assert np.all(_a_ahead(record, "hdl32_left") > near + 0.15)  # 40 ms before: 0.28 m farther
        assert np.all(_a_ahead(record, "hdl32_right") < near - 0.1)  # 30 ms after: 0.21 m nearer
    # one topic alone needs three frames (paper N §4.2), here on a moving vehicle
    top = _records(rig_bag, tmp_path / "top", "--topic", "/top", "--poses-topic", "/odom")
    assert [r["n_obstacles"] for r in top] == [0, 0, 1, 1]
    assert "clouds" not in top[0]
    # a window narrower than the sensors' offsets leaves the side clouds out, and says so
    narrow = _records(rig_bag, tmp_path / "narrow", *CLOUDS, "--sync-window", "0.02")
    assert all([c["topic"] for c in r["clouds"]] == ["/top"] for r in narrow)
    assert set(narrow[0]["frame_pairs"]) == {"hdl64"}
    assert "for /left in 4 of 4 updates, /right in 4 of 4 updates" in capsys.readouterr().err
    _records(rig_bag, tmp_path / "between", *CLOUDS, "--sync-window", "0.035")
    assert "for /left in 4 of 4 updates\n" in capsys.readouterr().err  # the right's 30 ms fit


def test_each_topic_mounted_by_its_own_frame_in_the_tf_tree(rig_bag, tmp_path, capsys) -> None:
    odometry_run = _records(rig_bag, tmp_path / "odom", *CLOUDS, "--poses-topic", "/odom")
    tf_run = _records(rig_bag, tmp_path / "tf", *CLOUDS, "--tf", "odom:base_link", "--mount-from-tf")
    assert "deg from the --sensor" not in capsys.readouterr().err
    for by_odometry, by_tf in zip(odometry_run, tf_run, strict=True):
        np.testing.assert_allclose(by_tf["pose"], by_odometry["pose"], atol=1e-9)
        for a, b in zip(by_tf["clouds"], by_odometry["clouds"], strict=True):
            assert a["topic"] == b["topic"]
            np.testing.assert_allclose(a["mounting"]["rotation"], b["mounting"]["rotation"], atol=1e-9)
            np.testing.assert_allclose(
                a["mounting"]["translation_m"], b["mounting"]["translation_m"], atol=1e-9
            )
            for key in ("rotation", "translation_m"):
                np.testing.assert_allclose(a["motion"][key], b["motion"][key], atol=1e-9)
        for sensor, pairs in by_odometry["frame_pairs"].items():
            np.testing.assert_allclose(by_tf["frame_pairs"][sensor]["a_m"], pairs["a_m"], atol=1e-3)
    # a side LiDAR named as the top one: its tf mounting is rolled 90 deg from --sensor's
    swapped = ["--cloud", "/left:hdl64", "--cloud", "/top:hdl32-left"]
    assert (
        main(
            [
                "-q",
                "detect",
                str(rig_bag),
                "--no-png",
                "--out",
                str(tmp_path / "s"),
                *swapped,
                "--tf",
                "odom:base_link",
                "--mount-from-tf",
            ]
        )
        == 0
    )
    assert capsys.readouterr().err.count("90.0 deg from the --sensor") == 2


def test_the_rig_with_a_png_per_update(rig_bag, tmp_path) -> None:
    out = tmp_path / "png"
    assert main(["-q", "detect", str(rig_bag), "--out", str(out), *CLOUDS[:4], "--sync-window", "0.05"]) == 0
    assert sorted(p.name for p in out.glob("*.png")) == [f"{k:05d}_rig_{k:04d}.png" for k in range(FRAMES)]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--cloud", "/top:hdl64", "--cloud", "/left:vlp16"], "both feed the detector's hdl64 input"),
        (["--cloud", "/top:hdl64", "--topic", "/top"], "drop --topic"),
        (["--cloud", "/top:hdl64", "--sensor", "hdl64", "--height", "2"], "drop --sensor, --height"),
        (["--cloud", "/top:hdl64", "--cloud", "/top:hdl32-left"], "names /top twice"),
        (["--cloud", "/rear:hdl64"], "no PointCloud2 topic '/rear'"),
        (["--sync-window", "0.05"], "--sync-window goes with --cloud"),
        (["--cloud", "/top:hdl64:2.0", "--tf", "odom:base_link", "--mount-from-tf"], "HEIGHT"),
        (["--cloud", "/top:hdl64", "--poses-topic", "/odom", "--deskew"], "no per-point time field"),
    ],
)
def test_rig_options_that_do_not_fit_are_refused_by_name(rig_bag, tmp_path, capsys, extra, message) -> None:
    assert main(["detect", str(rig_bag), "--out", str(tmp_path / "o"), *extra]) == 2
    assert message in capsys.readouterr().err


def test_cloud_specs_and_files_that_are_not_bags(tmp_path, capsys) -> None:
    scan = tmp_path / "f.bin"
    np.zeros((10, 4), dtype=np.float32).tofile(scan)
    assert main(["detect", str(scan), "--out", str(tmp_path / "o"), "--cloud", "/top:hdl64"]) == 2
    assert "not bags" in capsys.readouterr().err
    for bad in ("/top", "/top:lidar", "/top:hdl64:-1", ":hdl64"):
        with pytest.raises(SystemExit):
            main(["detect", str(scan), "--out", str(tmp_path / "o"), "--cloud", bad])
        assert "--cloud" in capsys.readouterr().err
