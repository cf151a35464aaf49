"""The transform tree: chains composed and inverted edge by edge, timed edges interpolated."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from negobs_gym.detector.io.poses import pose_from_ros_transform
from negobs_gym.detector.io.tf import TimedTransform, transform_chain
from negobs_gym.errors import ScanError

YAW_90 = tuple(Rotation.from_euler("z", 90, degrees=True).as_quat())
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def _odometry(times, speed_mps: float = 2.0) -> list[TimedTransform]:
    """odom -> base_link: driving along odom's x at ``speed_mps``, nose turning 0.1 rad/s."""
    return [
        TimedTransform(
            t,
            "odom",
            "base_link",
            (speed_mps * t, 0.0, 0.0),
            tuple(Rotation.from_euler("z", 0.1 * t).as_quat()),
        )
        for t in times
    ]


# map -> odom: the localiser's correction, 5 m along map's x and turned 90 deg; base_link ->
# velodyne: the roof sensor's mounting (ROS 1 names with tf's leading slash)
MAP_ODOM = TimedTransform(0.0, "map", "odom", (5.0, 0.0, 0.0), YAW_90)
MOUNT = TimedTransform(0.0, "/base_link", "/velodyne", (0.5, 0.0, 2.2), IDENTITY)


def _expected(t: float, speed_mps: float = 2.0) -> tuple[np.ndarray, Rotation]:
    """base_link in map at ``t``, composed by hand."""
    turn = Rotation.from_quat(YAW_90)
    return np.array([5.0, 0.0, 0.0]) + turn.apply([speed_mps * t, 0.0, 0.0]), turn * Rotation.from_euler(
        "z", 0.1 * t
    )


def _close(actual: tuple[np.ndarray, Rotation], expected: tuple[np.ndarray, Rotation]) -> None:
    np.testing.assert_allclose(actual[0], expected[0], atol=1e-9)
    assert (actual[1] * expected[1].inv()).magnitude() < 1e-9


def test_a_chain_composes_a_static_and_an_interpolated_edge() -> None:
    chain = transform_chain(_odometry([0.0, 0.5, 1.0]), [MAP_ODOM, MOUNT], "map", "base_link")
    assert chain.edges == ("map -> odom", "odom -> base_link")
    for t in (0.0, 0.25, 0.5, 0.8, 1.0):  # between samples: linear, and slerp about one axis
        _close(chain.transform_at(t), _expected(t))
    pose = chain.at(0.5)  # this package's pose: yaw 0 faces world +y, ROS yaw 0 world +x
    expected = pose_from_ros_transform(*_expected(0.5))
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((expected.x, expected.y, expected.yaw), abs=1e-9)
    assert pose.yaw == pytest.approx(0.05)  # ROS yaw 90 deg + 0.05 rad, less this package's 90 deg


def test_a_chain_walks_up_inverted_then_down() -> None:
    tree = (_odometry([0.0, 1.0]), [MAP_ODOM, MOUNT])
    back = transform_chain(*tree, "base_link", "map")
    assert back.edges == ("odom -> base_link^-1", "map -> odom^-1")
    position, rotation = _expected(0.6)
    inverse = rotation.inv()
    _close(back.transform_at(0.6), (-inverse.apply(position), inverse))
    # velodyne in odom: odom -> base_link -> velodyne; map in velodyne: up to map's child, inverted
    sensor = transform_chain(*tree, "odom", "velodyne")
    p, r = _odometry([0.6])[0].position_m, Rotation.from_euler("z", 0.06)
    _close(sensor.transform_at(0.6), (np.asarray(p) + r.apply([0.5, 0.0, 2.2]), r))
    sibling = transform_chain(*tree, "velodyne", "odom")
    assert sibling.edges == ("base_link -> velodyne^-1", "odom -> base_link^-1")


def test_equal_times_keep_the_later_transform_and_gaps_are_named() -> None:
    republished = [*_odometry([0.0, 1.0]), *_odometry([1.0], speed_mps=3.0)]  # the later one at t = 1
    chain = transform_chain(republished, [MAP_ODOM], "odom", "base_link", max_gap_s=0.05)
    assert chain.transform_at(1.0)[0][0] == pytest.approx(3.0)
    assert chain.transform_at(1.04)[0][0] == pytest.approx(3.0)  # within the gap: the last one
    with pytest.raises(ScanError, match=r"tf odom -> base_link: no pose at t = 1.100 s"):
        chain.at(1.1)


@pytest.mark.parametrize(
    ("timed", "static", "frames", "match"),
    [
        (_odometry([0.0]), [MAP_ODOM], ("map", "lidar"), r"no frame 'lidar'"),
        (
            _odometry([0.0]),
            [TimedTransform(0.0, "map", "base_link", (0.0, 0.0, 0.0), IDENTITY)],
            ("map", "base_link"),
            "'base_link' has two parents, 'odom' and 'map'",
        ),
        (
            _odometry([0.0]),
            [TimedTransform(0.0, "odom", "base_link", (0, 0, 0), IDENTITY)],
            ("odom", "base_link"),
            "both on /tf and /tf_static",
        ),
        (
            _odometry([0.0]),
            [TimedTransform(0.0, "earth", "gps", (0.0, 0.0, 0.0), IDENTITY)],
            ("earth", "base_link"),
            "separate trees",
        ),
        (
            [],
            [
                TimedTransform(0.0, "a", "b", (0.0, 0.0, 0.0), IDENTITY),
                TimedTransform(0.0, "b", "a", (0.0, 0.0, 0.0), IDENTITY),
            ],
            ("a", "b"),
            "form a loop",
        ),
        (
            _odometry([0.0]),
            [TimedTransform(0.0, "map", "odom", (math.nan, 0, 0), IDENTITY)],
            ("map", "base_link"),
            "map -> odom: a position",
        ),
        (
            _odometry([0.0]),
            [TimedTransform(0.0, "map", "odom", (0, 0, 0), (0, 0, 0, 0))],
            ("map", "base_link"),
            "zero length",
        ),
        (
            [*_odometry([0.0]), TimedTransform(0.5, "odom", "base_link", (0, 0, 0), (0, 0, 0, 0))],
            [],
            ("odom", "base_link"),
            "odom -> base_link: pose track: a quaternion has zero length",
        ),
    ],
)
def test_bad_trees_are_named(timed, static, frames, match) -> None:
    with pytest.raises(ScanError, match=match):
        transform_chain(timed, static, *frames)


def test_a_ros1_bag_tf_tree_with_slashed_frames(tmp_path) -> None:
    """ROS 1 tf: ``/odom`` -> ``/base_link`` on /tf, ``/base_link`` -> ``/velodyne`` on
    /tf_static (latched once), read by record time or header stamps."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from negobs_gym.detector.io.bags import bag_transform_chain

    store = get_typestore(Stores.ROS1_NOETIC)  # has no tf2_msgs: registered from its definition
    store.register(
        get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage")
    )
    t = store.types

    def message(stamp_ns: int, transforms) -> bytes:
        stamped = [
            t["geometry_msgs/msg/TransformStamped"](
                header=t["std_msgs/msg/Header"](
                    seq=0,
                    stamp=t["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
                    frame_id=parent,
                ),
                child_frame_id=child,
                transform=t["geometry_msgs/msg/Transform"](
                    translation=t["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=z),
                    rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                ),
            )
            for parent, child, x, z in transforms
        ]
        return store.serialize_ros1(t["tf2_msgs/msg/TFMessage"](transforms=stamped), "tf2_msgs/msg/TFMessage")

    bag = tmp_path / "tf.bag"
    with Writer(bag) as writer:
        static = writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=store)
        dynamic = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        writer.write(static, 10**9, message(10**9, [("/base_link", "/velodyne", 0.5, 2.2)]))
        for k in range(11):  # 10 Hz, 1 m/s along x; recorded 50 ms after the stamp
            stamp = 10**9 + k * 10**8
            writer.write(dynamic, stamp + 5 * 10**7, message(stamp, [("/odom", "/base_link", 0.1 * k, 0.0)]))
    by_header = bag_transform_chain(bag, "odom", "velodyne", stamps="header")
    assert by_header.edges == ("odom -> base_link", "base_link -> velodyne")
    np.testing.assert_allclose(by_header.transform_at(1.55)[0], [0.55 + 0.5, 0.0, 2.2], atol=1e-9)
    by_record = bag_transform_chain(bag, "/odom", "/base_link")  # 50 ms later: 5 cm behind
    np.testing.assert_allclose(by_record.transform_at(1.55)[0], [0.50, 0.0, 0.0], atol=1e-9)
    with pytest.raises(ScanError, match=r"tf\.bag: tf: no frame 'map'"):
        bag_transform_chain(bag, "map", "base_link")


def _matrix(tf: TimedTransform) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_quat(tf.quaternion_xyzw).as_matrix()
    out[:3, 3] = tf.position_m
    return out


@st.composite
def random_trees(draw) -> tuple[list[TimedTransform], str, str]:
    """A random static tree of up to 7 frames (each frame's parent an earlier frame) and two of its
    frames."""
    n = draw(st.integers(2, 7))
    floats = st.floats(-10.0, 10.0, allow_nan=False)
    edges = []
    for child in range(1, n):
        parent = draw(st.integers(0, child - 1))
        position = tuple(draw(floats) for _ in range(3))
        quaternion = tuple(draw(st.floats(-1.0, 1.0, allow_nan=False)) for _ in range(4))
        if np.linalg.norm(quaternion) < 0.1:
            quaternion = IDENTITY
        edges.append(TimedTransform(0.0, f"f{parent}", f"f{child}", position, quaternion))
    a, b = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
    return edges, f"f{a}", f"f{b}"


@settings(max_examples=100, deadline=None)
@given(random_trees())
def test_a_chain_is_the_product_of_the_tree_s_matrices(tree) -> None:
    """Against 4x4 matrices: each frame's pose in the root is the product down its path, and the
    chain from a to b is root-to-a inverted times root-to-b."""
    edges, a, b = tree
    parent = {e.child: e for e in edges}

    def in_root(frame: str) -> np.ndarray:
        return in_root(parent[frame].parent) @ _matrix(parent[frame]) if frame in parent else np.eye(4)

    want = np.linalg.inv(in_root(a)) @ in_root(b)
    position, rotation = transform_chain([], edges, a, b).transform_at(0.0)
    np.testing.assert_allclose(position, want[:3, 3], atol=1e-9)
    np.testing.assert_allclose(rotation.as_matrix(), want[:3, :3], atol=1e-9)


def test_mounting_difference_reads_the_setup_in_ros_axes() -> None:
    """A sensor rolled and turned on the vehicle (as the paper rig's side HDL-32s): a tf mounting it
    as its ScanSetup does differs by 0 deg, one pitched 2 deg more by 2; a frame not in the tree:
    None."""
    from negobs_gym.detector.io import ScanSetup
    from negobs_gym.detector.io.setup import PACKAGE_TO_ROS_BODY
    from negobs_gym.detector.io.tf import TransformTree, mounting_difference_deg

    rotation = Rotation.from_euler("xyz", [0.3, 1.2, -0.4]).as_matrix()  # sensor to vehicle, package axes
    setup = ScanSetup(rotation=tuple(tuple(float(v) for v in row) for row in rotation))
    on_vehicle = Rotation.from_matrix(PACKAGE_TO_ROS_BODY @ rotation @ PACKAGE_TO_ROS_BODY.T)
    for extra_deg in (0.0, 2.0):
        mount = on_vehicle * Rotation.from_euler("y", extra_deg, degrees=True)
        tree = TransformTree(
            [], [TimedTransform(0.0, "base_link", "left", (0.0, 0.5, 2.0), tuple(mount.as_quat()))]
        )
        assert mounting_difference_deg(tree, "base_link", "left", setup, 0.0) == pytest.approx(
            extra_deg, abs=1e-9
        )
    assert mounting_difference_deg(tree, "base_link", "velodyne", setup, 0.0) is None
    # the cloud's frame in another tree, or mounted by a timed edge that does not reach the time:
    # the tree cannot say, which is no answer (the check is advisory), not an error
    apart = TransformTree(
        [],
        [
            TimedTransform(0.0, "rig", "left", (0, 0, 0), IDENTITY),
            TimedTransform(0.0, "odom", "base_link", (0, 0, 0), IDENTITY),
        ],
    )
    assert mounting_difference_deg(apart, "base_link", "left", setup, 0.0) is None
    timed = TransformTree([TimedTransform(5.0, "base_link", "left", (0, 0, 0), tuple(mount.as_quat()))], [])
    assert mounting_difference_deg(timed, "base_link", "left", setup, 0.0) is None
    assert mounting_difference_deg(timed, "base_link", "left", setup, 5.0) == pytest.approx(2.0, abs=1e-9)
    # the same rotation read in package axes (no conversion) would not match: the check is not vacuous
    assert np.degrees((Rotation.from_matrix(rotation).inv() * on_vehicle).magnitude()) > 5.0


def test_sensor_mounting_is_the_setup_a_rig_mount_would_give() -> None:
    """The paper rig's left HDL-32 (rolled 90 deg, 0.9 m off the centre line) written as a tf
    mounting below a base_link 0.35 m above the ground reads back as that mount's R and T."""
    from negobs_gym.detector.io.setup import PACKAGE_TO_ROS_BODY as TO_ROS
    from negobs_gym.detector.io.tf import TransformTree, sensor_mounting
    from negobs_gym.sensors.rigs import paper_n_rig

    mount = next(m for m in paper_n_rig().mounts if m.name == "hdl32_left")
    rotation, translation = np.asarray(mount.rotation_matrix), np.asarray(mount.translation_m)
    quaternion = Rotation.from_matrix(TO_ROS @ rotation @ TO_ROS.T).as_quat()
    position = TO_ROS @ (translation - [0.0, 0.0, 0.35])
    tree = TransformTree([], [TimedTransform(0.0, "base_link", "left", tuple(position), tuple(quaternion))])
    got_rotation, got_translation = sensor_mounting(tree, "base_link", "left", 0.0, body_height_m=0.35)
    np.testing.assert_allclose(got_rotation, rotation, atol=1e-12)
    np.testing.assert_allclose(got_translation, translation, atol=1e-12)
    with pytest.raises(ScanError, match="no frame 'right'"):
        sensor_mounting(tree, "base_link", "right", 0.0)
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ScanError, match="body_height_m"):
            sensor_mounting(tree, "base_link", "left", 0.0, body_height_m=bad)
        with pytest.raises(ScanError, match="body_height_m"):
            tree.chain("base_link", "left", body_height_m=bad)


def test_a_body_height_lowers_the_chain_along_the_body_s_up_axis() -> None:
    """base_link 1 m up, pitched 10 deg nose down: the ground point 0.5 m below it lies behind."""
    from negobs_gym.detector.io.tf import TransformTree

    pitch = Rotation.from_euler("y", 10, degrees=True)
    tree = TransformTree(
        [], [TimedTransform(0.0, "odom", "base_link", (5.0, 0.0, 1.0), tuple(pitch.as_quat()))]
    )
    position, rotation = tree.chain("odom", "base_link", body_height_m=0.5).transform_at(0.0)
    s, c = math.sin(math.radians(10)), math.cos(math.radians(10))
    np.testing.assert_allclose(position, [5.0 - 0.5 * s, 0.0, 1.0 - 0.5 * c], atol=1e-12)
    assert (rotation * pitch.inv()).magnitude() < 1e-12
