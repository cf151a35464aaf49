"""ROS 1 / ROS 2 bags with ``sensor_msgs/PointCloud2`` (``rosbags``, extra ``negobs_gym[real]``; no
ROS install needed). A bag is a sequence: one frame per message of one topic, in time order. An
odometry or pose topic of the same bag gives the drive's poses (:func:`bag_pose_track`), or its
transform tree does (:func:`bag_transform_tree`, :func:`bag_transform_chain`)."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io._optional import optional_import
from negobs_gym.detector.io.frame import RecordedFrame, check_not_empty, unreadable
from negobs_gym.detector.io.poses import PoseTrack
from negobs_gym.detector.io.setup import RING_FIELD_NAMES, ScanSetup, column_time_offsets, fields_to_scan
from negobs_gym.detector.io.tf import TimedTransform, TransformChain, TransformTree, frame_name
from negobs_gym.errors import ScanError

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
# message types with a pose, and how to reach its geometry_msgs/Pose
POSE_MESSAGES = {
    "nav_msgs/msg/Odometry": lambda m: m.pose.pose,
    "geometry_msgs/msg/PoseStamped": lambda m: m.pose,
    "geometry_msgs/msg/PoseWithCovarianceStamped": lambda m: m.pose.pose,
}
# transform-tree messages (``/tf``, ``/tf_static``): tf2's, and ROS 1 tf's older name
TF_MESSAGES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")
# what times a bag's messages: when the recorder received them, or the stamp in their header
# (the sensor's and the odometry's own clocks, without the transport's latency)
STAMPS = ("record", "header")
# sensor_msgs/PointField datatype codes -> numpy scalar types
_POINTFIELD_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def pointcloud2_fields(msg: object, source: str) -> dict[str, np.ndarray]:
    """The per-point fields of a PointCloud2 message as numpy arrays (padding and row steps honoured)."""
    endian = ">" if msg.is_bigendian else "<"  # type: ignore[attr-defined]
    names, formats, offsets = [], [], []
    for f in msg.fields:  # type: ignore[attr-defined]
        if f.datatype not in _POINTFIELD_DTYPES:
            raise ScanError(f"{source}: field {f.name!r} has unknown PointField datatype {f.datatype}")
        names.append(f.name)
        formats.append(
            (endian + _POINTFIELD_DTYPES[f.datatype], (f.count,))
            if f.count > 1
            else endian + _POINTFIELD_DTYPES[f.datatype]
        )
        offsets.append(f.offset)
    width, height = int(msg.width), int(msg.height)  # type: ignore[attr-defined]
    point_step, row_step = int(msg.point_step), int(msg.row_step)  # type: ignore[attr-defined]
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)  # type: ignore[attr-defined]
    if point_step <= 0 or row_step < width * point_step or data.size < height * row_step:
        raise ScanError(
            f"{source}: PointCloud2 holds {data.size} bytes, {height} rows x {row_step} bytes expected "
            f"(width {width}, point_step {point_step}; truncated message?)"
        )
    try:
        dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})
    except ValueError as error:
        raise ScanError(
            f"{source}: PointCloud2 fields do not fit point_step {point_step} ({error})"
        ) from error
    rows = data[: height * row_step].reshape(height, row_step)[:, : width * point_step]
    points = np.ascontiguousarray(rows).view(dtype).reshape(-1)
    return {name: points[name] for name in names}


def _message_time_s(stamp_ns: int, msg: object, stamps: str, source: str) -> float:
    """A message's time [s]: the bag's record time, or its ``header.stamp`` (``stamps``)."""
    if stamps == "record":
        return stamp_ns * 1e-9
    stamp = msg.header.stamp  # type: ignore[attr-defined]
    seconds = int(stamp.sec) + int(stamp.nanosec) * 1e-9
    if seconds <= 0.0:
        raise ScanError(
            f"{source}: header stamp is {seconds} (not stamped by its driver): use the record time"
        )
    return seconds


def _check_stamps(stamps: str) -> None:
    if stamps not in STAMPS:
        raise ScanError(f"stamps must be one of {STAMPS}, got {stamps!r}")


def bag_frames(
    path: str | os.PathLike[str],
    setup: ScanSetup,
    *,
    topic: str | None = None,
    stamps: str = "record",
    point_times: bool = False,
) -> Iterator[RecordedFrame]:
    """Frames of the PointCloud2 ``topic`` of a ROS 1 ``.bag`` or ROS 2 bag (folder, ``.db3``,
    ``.mcap``) in record order; without ``topic`` the bag must hold exactly one PointCloud2 topic.
    Each scan's ``timestamp_s`` is the message's record time, or with ``stamps="header"`` its
    header stamp (an unstamped message, 0, is an error). With ``point_times`` each frame's
    ``column_time_s`` is read from its points' time field (an error where there is none)."""
    _check_stamps(stamps)
    p = Path(path)
    reader = _open_bag(p)
    try:
        clouds = _cloud_topics(reader)
        if topic is None and len(clouds) != 1:
            raise ScanError(f"{p}: {len(clouds)} PointCloud2 topics {clouds}; name one with topic=")
        for _, frame in _read_clouds(reader, p, {topic or clouds[0]: setup}, stamps, point_times):
            yield frame
    finally:
        reader.close()


def bag_clouds(
    path: str | os.PathLike[str],
    setups: Mapping[str, ScanSetup],
    *,
    stamps: str = "record",
    point_times: bool = False,
) -> Iterator[tuple[str, RecordedFrame]]:
    """The clouds of several PointCloud2 topics of a bag (a rig of LiDARs, one topic each), each
    topic read with its own setup, as ``(topic, frame)`` merged in record order; a frame's
    ``index`` counts its own topic's clouds. Timed (and ``point_times`` read) as
    :func:`bag_frames`; grouped into detector updates by
    :func:`~negobs_gym.detector.io.sync.synchronise`."""
    _check_stamps(stamps)
    if not setups:
        raise ScanError("bag_clouds: name at least one PointCloud2 topic")
    p = Path(path)
    reader = _open_bag(p)
    try:
        yield from _read_clouds(reader, p, setups, stamps, point_times)
    finally:
        reader.close()


def _cloud_topics(reader) -> list[str]:
    return sorted({c.topic for c in reader.connections if c.msgtype == POINTCLOUD2})


def _read_clouds(
    reader, p: Path, setups: Mapping[str, ScanSetup], stamps: str, point_times: bool = False
) -> Iterator[tuple[str, RecordedFrame]]:
    """``(topic, frame)`` of the topics of ``setups`` in record order (an opened reader)."""
    clouds = _cloud_topics(reader)
    missing = [topic for topic in setups if topic not in clouds]
    if missing:
        raise ScanError(f"{p}: no PointCloud2 topic {' or '.join(map(repr, missing))} (has {clouds})")
    connections = [c for c in reader.connections if c.topic in setups]
    counts = dict.fromkeys(setups, 0)
    for connection, stamp_ns, raw in reader.messages(connections=connections):
        topic = connection.topic
        index = counts[topic]
        counts[topic] += 1
        source = f"{p}#{index}" if len(setups) == 1 else f"{p}#{topic}#{index}"
        msg = _deserialize(reader, connection, raw, source)
        fields = pointcloud2_fields(msg, source)
        time_s = _message_time_s(stamp_ns, msg, stamps, source)
        scan, ring_source = fields_to_scan(fields, setups[topic], source=source, timestamp_s=time_s)
        columns = None
        if point_times:
            stamp = msg.header.stamp
            stamp_s = int(stamp.sec) + int(stamp.nanosec) * 1e-9
            columns = column_time_offsets(fields, setups[topic], source=source, stamp_s=stamp_s)
        points = int(msg.width) * int(msg.height)
        frame = RecordedFrame(scan, os.fspath(p), index, ring_source, points, msg.header.frame_id, columns)
        yield topic, frame


def _open_bag(p: Path):
    """An opened rosbags ``AnyReader`` of the bag at ``p`` (its folder, or a ``.db3``/``.mcap`` in it)."""
    highlevel = optional_import("rosbags.highlevel", "rosbags", "reading ROS bags")
    bag = p.parent if p.suffix.lower() in (".db3", ".mcap") else p
    check_not_empty(os.fspath(p))
    try:
        reader = highlevel.AnyReader([bag])
        reader.open()
    except Exception as error:  # rosbags raises its own ReaderError / AnyReaderError on bad bags
        raise unreadable(os.fspath(p), "ROS bag", error) from error
    return reader


def bag_pose_track(
    path: str | os.PathLike[str], topic: str, *, max_gap_s: float = 0.1, stamps: str = "record"
) -> PoseTrack:
    """The poses of ``topic`` in a bag (``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or
    ``PoseWithCovarianceStamped``), timed as :func:`bag_frames` times its frames with the same
    ``stamps`` (record time, or header stamps in time order), for :meth:`PoseTrack.at`.

    Raises:
        ScanError: not a readable bag, no such topic or not a pose type, no message, a message
            that cannot be read, an unstamped message (``stamps="header"``), or two poses at one
            time.
    """
    _check_stamps(stamps)
    p = Path(path)
    reader = _open_bag(p)
    try:
        types = {c.topic: c.msgtype for c in reader.connections}
        if topic not in types:
            raise ScanError(f"{p}: no topic {topic!r} (has {sorted(types)})")
        if types[topic] not in POSE_MESSAGES:
            raise ScanError(f"{p}: {topic} is {types[topic]}, not one of {sorted(POSE_MESSAGES)}")
        pose_of = POSE_MESSAGES[types[topic]]
        times, rows = [], []
        connections = [c for c in reader.connections if c.topic == topic]
        for index, (connection, stamp_ns, raw) in enumerate(reader.messages(connections=connections)):
            source = f"{p}#{topic}#{index}"
            try:
                msg = reader.deserialize(raw, connection.msgtype)
                pose = pose_of(msg)
            except Exception as error:  # a corrupt message body
                raise unreadable(source, types[topic], error) from error
            o, q = pose.position, pose.orientation
            times.append(_message_time_s(stamp_ns, msg, stamps, source))
            rows.append((o.x, o.y, o.z, q.x, q.y, q.z, q.w))
    finally:
        reader.close()
    if not rows:
        raise ScanError(f"{p}: no message on {topic}")
    order = np.argsort(times, kind="stable")  # header stamps need not come in record order
    data = np.asarray(rows, dtype=np.float64)[order]
    return PoseTrack(np.asarray(times)[order], data[:, :3], data[:, 3:], max_gap_s=max_gap_s)


def bag_transform_tree(path: str | os.PathLike[str], *, stamps: str = "record") -> TransformTree:
    """The transform tree of a bag's ``/tf`` and ``/tf_static`` (``tf2_msgs/TFMessage``;
    :mod:`~negobs_gym.detector.io.tf`), each transform timed as :func:`bag_frames` times its frames
    with the same ``stamps`` (the message's record time, or the transform's header stamp).

    Raises:
        ScanError: not a readable bag, no tf topic, a message that cannot be read, an unstamped
            transform (``stamps="header"``), a frame with two parents.
    """
    _check_stamps(stamps)
    p = Path(path)
    reader = _open_bag(p)
    timed: list[TimedTransform] = []
    static: list[TimedTransform] = []
    try:
        topics = sorted({c.topic for c in reader.connections if c.msgtype in TF_MESSAGES})
        if not topics:
            types = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            raise ScanError(f"{p}: no tf topic ({' or '.join(TF_MESSAGES)}); the bag has {types}")
        for stamp_ns, is_static, stamped, source in _transforms(reader, p):
            t, q = stamped.transform.translation, stamped.transform.rotation
            (static if is_static else timed).append(
                TimedTransform(
                    0.0 if is_static else _message_time_s(stamp_ns, stamped, stamps, source),
                    stamped.header.frame_id,
                    stamped.child_frame_id,
                    (float(t.x), float(t.y), float(t.z)),
                    (float(q.x), float(q.y), float(q.z), float(q.w)),
                )
            )
    finally:
        reader.close()
    return TransformTree(timed, static, source=os.fspath(p))


def bag_transform_chain(
    path: str | os.PathLike[str],
    fixed: str,
    body: str,
    *,
    max_gap_s: float = 0.1,
    stamps: str = "record",
) -> TransformChain:
    """Where frame ``body`` (e.g. ``base_link``) is in frame ``fixed`` (``odom``, ``map``) by the
    bag's transform tree (:func:`bag_transform_tree`), for :meth:`TransformChain.at`.

    Raises:
        ScanError: as :func:`bag_transform_tree`, or a tree without a chain between the two frames.
    """
    return bag_transform_tree(path, stamps=stamps).chain(fixed, body, max_gap_s=max_gap_s)


def read_bag(
    path: str | os.PathLike[str], setup: ScanSetup | None = None, *, topic: str | None = None
) -> Iterator[StructuredScan]:
    """The structured scans of a bag's PointCloud2 topic (see :func:`bag_frames`)."""
    return (frame.scan for frame in bag_frames(path, setup or ScanSetup(), topic=topic))


@dataclass(frozen=True)
class BagTopic:
    """One topic of a bag as ``negobs detect`` may read it.

    Attributes:
        topic: Its name.
        msgtype: Its message type (``sensor_msgs/msg/PointCloud2``...).
        count: Messages on it.
        frame_id: The first message's ``header.frame_id`` (clouds, poses), else None.
        child_frame_id: The first odometry message's ``child_frame_id`` (the body it tracks), else None.
        fields: The first cloud's PointField names (``ring``: no elevation table needed).
        points: Points in the first cloud.
        rings: Rings with returns in the first cloud, by its ring field (``RING_FIELD_NAMES``: up
            to 4 for a LUX, 64 for an HDL-64E), 0 without one.
    """

    topic: str
    msgtype: str
    count: int
    frame_id: str | None = None
    child_frame_id: str | None = None
    fields: tuple[str, ...] = ()
    points: int = 0
    rings: int = 0


@dataclass(frozen=True)
class TransformEdge:
    """One edge of a bag's tf tree: ``parent -> child``, on ``/tf_static`` or timed, how often."""

    parent: str
    child: str
    static: bool
    count: int


@dataclass(frozen=True)
class BagContents:
    """What a bag holds for ``negobs detect``: its span, topics, and tf tree's edges."""

    path: str
    duration_s: float
    topics: tuple[BagTopic, ...]
    tf_edges: tuple[TransformEdge, ...]

    def of_type(self, *msgtypes: str) -> tuple[BagTopic, ...]:
        """The topics of any of ``msgtypes``."""
        return tuple(t for t in self.topics if t.msgtype in msgtypes)


def bag_contents(path: str | os.PathLike[str]) -> BagContents:
    """The topics of a bag (each cloud and pose topic's first message read for its frame and
    fields) and its tf tree's edges (every tf message read; no cloud beyond the first).

    Raises:
        ScanError: not a readable bag, or a first message or tf message that cannot be read.
    """
    p = Path(path)
    reader = _open_bag(p)
    edges: dict[tuple[str, str, bool], int] = {}
    try:
        topics = []
        for topic, info in sorted(reader.topics.items()):
            entry = BagTopic(topic, info.msgtype, int(info.msgcount))
            if info.msgtype == POINTCLOUD2 or info.msgtype in POSE_MESSAGES:
                msg = _first_message(reader, info.connections, f"{p}#{topic}")
                if msg is not None:
                    entry = dataclasses.replace(
                        entry,
                        frame_id=msg.header.frame_id,
                        child_frame_id=getattr(msg, "child_frame_id", None),
                        fields=tuple(f.name for f in getattr(msg, "fields", ())),
                        points=int(msg.width) * int(msg.height) if info.msgtype == POINTCLOUD2 else 0,
                        rings=_rings(msg, f"{p}#{topic}") if info.msgtype == POINTCLOUD2 else 0,
                    )
            topics.append(entry)
        for _, static, stamped, _ in _transforms(reader, p):
            key = (stamped.header.frame_id, stamped.child_frame_id, static)
            edges[key] = edges.get(key, 0) + 1
        duration_s = reader.duration * 1e-9 if reader.message_count else 0.0
    finally:
        reader.close()
    tf_edges = tuple(TransformEdge(parent, child, static, n) for (parent, child, static), n in edges.items())
    return BagContents(os.fspath(p), duration_s, tuple(topics), tf_edges)


def _rings(msg: object, source: str) -> int:
    """How many distinct rings a cloud's ring field holds over its points with coordinates (0: none)."""
    name = next((f.name for f in msg.fields if f.name in RING_FIELD_NAMES), None)  # type: ignore[attr-defined]
    if name is None:
        return 0
    fields = pointcloud2_fields(msg, source)
    xyz = np.column_stack([np.asarray(fields[k], dtype=np.float64).reshape(-1) for k in "xyz" if k in fields])
    ring = np.asarray(fields[name]).reshape(-1)
    return int(np.unique(ring[np.isfinite(xyz).all(axis=1)] if xyz.shape[1] == 3 else ring).size)


def _first_message(reader, connections, source: str):
    """The first message on ``connections`` (deserialised), None on an empty topic."""
    for connection, _, raw in reader.messages(connections=connections):
        return _deserialize(reader, connection, raw, source)
    return None


def _transforms(reader, p: Path) -> Iterator[tuple[int, bool, object, str]]:
    """``(record time [ns], static, TransformStamped, source)`` of every transform on the bag's tf
    topics, in record order (none without a tf topic)."""
    connections = [c for c in reader.connections if c.msgtype in TF_MESSAGES]
    if not connections:  # rosbags reads every topic when given none
        return
    for index, (connection, stamp_ns, raw) in enumerate(reader.messages(connections=connections)):
        source = f"{p}#{connection.topic}#{index}"
        msg = _deserialize(reader, connection, raw, source)
        static = frame_name(connection.topic) == "tf_static"
        for stamped in msg.transforms:  # type: ignore[attr-defined]
            yield stamp_ns, static, stamped, source


def _deserialize(reader, connection, raw: bytes, source: str) -> object:
    """One message's body, or a one-line :class:`ScanError` naming ``source`` if it is corrupt."""
    try:
        return reader.deserialize(raw, connection.msgtype)
    except Exception as error:  # rosbags raises its own errors on a corrupt message body
        raise unreadable(source, connection.msgtype, error) from error
