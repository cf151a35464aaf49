"""``negobs bag``: a bag's clouds, poses and tf tree, as ``negobs detect``'s options name them."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.detector.io.bags import BagTopic, TransformEdge, bag_contents
from tests.cli.test_detect_rig import FRAMES, rig_bag  # noqa: F401  (the fixture)
from tests.helpers import pointcloud2


def test_the_rig_bag_lists_its_three_lidars_odometry_and_tf_tree(rig_bag, capsys) -> None:  # noqa: F811
    contents = bag_contents(rig_bag)
    clouds = {t.topic: t for t in contents.topics if t.msgtype == "sensor_msgs/msg/PointCloud2"}
    assert sorted(clouds) == ["/left", "/right", "/top"]
    fields = ("x", "y", "z", "intensity", "ring")
    cloud_type = "sensor_msgs/msg/PointCloud2"
    assert clouds["/top"] == BagTopic("/top", cloud_type, FRAMES, "top", None, fields, 224_000, rings=56)
    assert clouds["/left"].rings == 32  # the top HDL-64's 8 highest lasers see only sky
    (odom,) = contents.of_type("nav_msgs/msg/Odometry")
    assert (odom.frame_id, odom.child_frame_id, odom.count) == ("odom", "base_link", 30)
    edges = set(contents.tf_edges)
    assert TransformEdge("odom", "base_link", False, 30) in edges
    mounts = {(e.parent, e.child) for e in edges if e.static}
    assert mounts == {("base_link", lidar) for lidar in ("top", "left", "right")}
    assert main(["bag", str(rig_bag)]) == 0
    out = capsys.readouterr().out
    assert f"/top  {FRAMES} clouds" in out and "frame left" in out
    assert "224000 points  56 rings  fields" in out
    assert "/odom  nav_msgs/msg/Odometry  30" in out and "odom -> base_link" in out
    assert "odom -> base_link  timed, 30 transforms" in out and "base_link -> right  static" in out


def test_a_bag_without_poses_or_tf_says_none_and_lists_the_rest(tmp_path, capsys) -> None:
    pytest.importorskip("rosbags")
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    points = np.zeros(3, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    points["x"] = [1.0, 2.0, 3.0]
    bag = tmp_path / "plain.bag"
    with Writer(bag) as writer:
        cloud = writer.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=store)
        note = writer.add_connection("/note", "std_msgs/msg/String", typestore=store)
        msg = pointcloud2(store, points, 10**9, ros1=True)
        writer.write(cloud, 10**9, store.serialize_ros1(msg, "sensor_msgs/msg/PointCloud2"))
        text = store.types["std_msgs/msg/String"](data="hello")
        writer.write(note, 2 * 10**9, store.serialize_ros1(text, "std_msgs/msg/String"))
    assert main(["bag", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "1.0 s, 2 topics" in out
    assert "/points  1 clouds  frame velodyne  3 points  fields x y z" in out
    assert out.count("    none") == 2  # no poses, no tf
    assert "other: /note (std_msgs/msg/String, 1)" in out
    assert main(["bag", str(tmp_path / "missing.bag")]) == 2
    assert "not a readable ROS bag" in capsys.readouterr().err
