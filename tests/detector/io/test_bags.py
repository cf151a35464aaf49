"""ROS 1 / ROS 2 bags with sensor_msgs/PointCloud2, written here from the real HDL-32E frames."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.detector.io import ScanSetup, fields_to_scan, read_recording
from negobs_gym.detector.io.bags import bag_clouds, read_bag
from negobs_gym.detector.io.sync import synchronise
from negobs_gym.errors import ScanError
from tests.helpers import pointcloud2

from .conftest import HDL32E_A

pytest.importorskip("rosbags")
vd = pytest.importorskip("velodyne_decoder")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

TOPIC = "/velodyne_points"
SETUP = ScanSetup(azimuth_resolution_deg=0.16, translation_m=(0.0, 0.0, 2.3))


@pytest.fixture(scope="module")
def frames():
    """(stamp_ns, points) of the two real HDL-32E frames of hdl32e_a.pcap."""
    return [(int(s.host * 1e9), p) for s, p in vd.read_pcap(str(HDL32E_A), vd.Config(), as_pcl_structs=True)]


def write_bag(
    path, frames, ros: int, topics=(TOPIC,), data: bytes | None = None, header_ns=None, topic_lag_ns: int = 0
):
    """``frames`` as PointCloud2 messages recorded at their stamps, the ``i``-th topic's
    ``i * topic_lag_ns`` later; ``header_ns(stamp)`` gives each header's stamp (default: the record
    time)."""
    store = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    msgtype = "sensor_msgs/msg/PointCloud2"
    writer = Writer1(path) if ros == 1 else Writer2(path, version=9)
    with writer:
        for i, topic in enumerate(topics):
            conn = writer.add_connection(topic, msgtype, typestore=store)
            for stamp, points in frames:
                stamp += i * topic_lag_ns
                header = stamp if header_ns is None else header_ns(stamp)
                msg = pointcloud2(store, points, header, data, ros1=ros == 1)
                raw = store.serialize_ros1(msg, msgtype) if ros == 1 else store.serialize_cdr(msg, msgtype)
                writer.write(conn, stamp, raw)
    return path


@pytest.mark.parametrize(("ros", "name"), [(1, "drive.bag"), (2, "drive_ros2")])
def test_bag_frames_equal_the_recorded_points(tmp_path, frames, ros, name):
    bag = write_bag(tmp_path / name, frames, ros)
    got = list(read_recording(bag, SETUP))
    assert [f.index for f in got] == [0, 1] and all(f.ring_source == "ring_field" for f in got)
    for frame, (stamp, points) in zip(got, frames, strict=True):
        fields = {k: points[k] for k in ("x", "y", "z", "intensity", "ring")}
        direct, _ = fields_to_scan(fields, SETUP, source="points")
        np.testing.assert_array_equal(frame.scan.ranges_m, direct.ranges_m)
        assert frame.scan.timestamp_s == pytest.approx(stamp * 1e-9)
        assert frame.n_points == points.size


@pytest.mark.parametrize("ros", [1, 2])
def test_frames_timed_by_their_header_stamps(tmp_path, frames, ros):
    name = "{}.bag" if ros == 1 else "{}_ros2"
    bag = write_bag(tmp_path / name.format("late"), frames, ros, header_ns=lambda stamp: stamp - 40 * 10**6)
    recorded = [f.scan.timestamp_s for f in read_recording(bag, SETUP)]
    stamped = [f.scan.timestamp_s for f in read_recording(bag, SETUP, stamps="header")]
    assert recorded == pytest.approx([s * 1e-9 for s, _ in frames])
    np.testing.assert_allclose(np.subtract(recorded, stamped), 0.040, atol=1e-6)
    unstamped = write_bag(tmp_path / name.format("zero"), frames[:1], ros, header_ns=lambda stamp: 0)
    assert len(list(read_recording(unstamped, SETUP))) == 1  # the record time needs no stamp
    with pytest.raises(ScanError, match="header stamp is 0"):
        list(read_recording(unstamped, SETUP, stamps="header"))
    with pytest.raises(ScanError, match="stamps must be one of"):
        list(read_recording(unstamped, SETUP, stamps="sensor"))


def test_ros2_bag_by_its_db3_file_and_named_topic(tmp_path, frames):
    bag = write_bag(tmp_path / "two", frames[:1], 2, topics=("/a", "/b"))
    db3 = next(bag.glob("*.db3"))
    with pytest.raises(ScanError, match="2 PointCloud2 topics"):
        list(read_recording(db3, SETUP))
    with pytest.raises(ScanError, match="no PointCloud2 topic '/c'"):
        list(read_recording(db3, SETUP, topic="/c"))
    assert len(list(read_bag(db3, SETUP, topic="/b"))) == 1


@pytest.mark.parametrize("ros", [1, 2])
def test_several_topics_merge_in_record_order_and_group_by_the_lead(tmp_path, frames, ros):
    name = "rig.bag" if ros == 1 else "rig_ros2"
    at_10_hz = [(frames[0][0] + k * 10**8, points) for k, (_, points) in enumerate(frames)]
    bag = write_bag(tmp_path / name, at_10_hz, ros, topics=("/top", "/side"), topic_lag_ns=30 * 10**6)
    side = ScanSetup(sensor="hdl32_left", azimuth_resolution_deg=0.16, translation_m=(-0.9, 0.5, 2.0))
    clouds = list(bag_clouds(bag, {"/top": SETUP, "/side": side}))
    assert [(topic, f.index) for topic, f in clouds] == [("/top", 0), ("/side", 0), ("/top", 1), ("/side", 1)]
    alone = list(read_recording(bag, SETUP, topic="/top"))
    for (_, frame), single in zip(clouds[::2], alone, strict=True):
        np.testing.assert_array_equal(frame.scan.ranges_m, single.scan.ranges_m)
    assert {f.scan.sensor for _, f in clouds[1::2]} == {"hdl32_left"}
    updates = list(synchronise(iter(clouds), "/top", ["/side"]))
    assert [(u.lead.index, {t: f.index for t, f in u.clouds.items()}) for u in updates] == [
        (0, {"/top": 0, "/side": 0}),
        (1, {"/top": 1, "/side": 1}),
    ]
    lags = [u.clouds["/side"].scan.timestamp_s - u.time_s for u in updates]
    np.testing.assert_allclose(lags, 0.030, atol=1e-6)
    with pytest.raises(ScanError, match="no PointCloud2 topic '/rear'"):
        list(bag_clouds(bag, {"/top": SETUP, "/rear": side}))
    with pytest.raises(ScanError, match="at least one"):
        list(bag_clouds(bag, {}))


def test_truncated_message_data_raises_scan_error(tmp_path, frames):
    stamp, points = frames[0]
    bag = write_bag(tmp_path / "cut.bag", [(stamp, points)], 1, data=points.tobytes()[: points.nbytes // 2])
    with pytest.raises(ScanError, match="truncated message"):
        list(read_recording(bag, SETUP))


def test_bag_without_xyz_fields_raises_scan_error(tmp_path, frames):
    stamp, points = frames[0]
    no_z = points[["x", "y", "intensity", "ring"]]
    bag = write_bag(tmp_path / "noz.bag", [(stamp, no_z)], 1, data=no_z.tobytes())
    with pytest.raises(ScanError, match="no z field"):
        list(read_recording(bag, SETUP))


@pytest.mark.parametrize(
    ("content", "match"), [(b"", "file is empty"), (b"#ROSBAG V2.0\nnot a bag" * 5, "not a readable ROS bag")]
)
def test_bad_bag_files_raise_scan_error(tmp_path, content, match):
    bad = tmp_path / "bad.bag"
    bad.write_bytes(content)
    with pytest.raises(ScanError, match=match):
        list(read_recording(bad, SETUP))
