"""Helpers shared across the test packages."""

from __future__ import annotations

import os

import numpy as np

HAS_PROC_STATM = os.path.exists("/proc/self/statm")

# a 0.6 m deep pit under both wheel tracks at a station drawn from the env's generator
PIT_SCENE = """
name = "pit_0.6m"
terminations = ["entered_negative_obstacle", "trapped", "collision", "rollover", "goal", "stopped"]

[terrain.course]
length_m = 45.0

[[obstacles]]
kind = "pit"
length_m = 1.0
width_m = 2.5
depth_m = 0.6
station_m = [14.0, 20.0]

[start]
speed_mps = 6.944444444444445

[episode]
time_limit_s = 9.0

[task]
kind = "stop_before_hazard"

[criteria]
entered_negative_obstacle = false
stopped_before = true
min_stop_margin_m = 0.5
"""


def rss_mb() -> float:
    """Resident set size of this process [MB] (Linux /proc)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


# sensor_msgs/PointField datatype codes of the numpy field types the tests write
POINTFIELD_CODES = {np.dtype("<f4"): 7, np.dtype("<u2"): 4, np.dtype("u1"): 2}


def ros_ring_cloud(scan) -> np.ndarray:
    """A scan's returns as a driver's cloud: float32 ``x, y, z`` in the ROS frame, ``intensity``
    (0) and ``ring`` (the row), row by row."""
    from negobs_gym.detector.loaders import sensor_to_ros_frame

    xyz = sensor_to_ros_frame(scan.points_sensor[scan.valid])
    points = np.zeros(len(xyz), dtype=[(n, "<f4") for n in "xyz"] + [("intensity", "<f4"), ("ring", "<u2")])
    points["x"], points["y"], points["z"] = xyz.T
    points["ring"] = np.broadcast_to(np.arange(scan.shape[0])[:, None], scan.shape)[scan.valid]
    return points


def pointcloud2(
    store,
    points: np.ndarray,
    stamp_ns: int,
    data: bytes | None = None,
    ros1: bool = False,
    frame_id: str = "velodyne",
):
    """A PointCloud2 message holding ``points`` (a numpy structured array) as they lie in memory."""
    t = store.types
    msg_types = {
        "PointField": t["sensor_msgs/msg/PointField"],
        "PointCloud2": t["sensor_msgs/msg/PointCloud2"],
        "Header": t["std_msgs/msg/Header"],
        "Time": t["builtin_interfaces/msg/Time"],
    }
    fields = [
        msg_types["PointField"](
            name=n,
            offset=points.dtype.fields[n][1],
            datatype=POINTFIELD_CODES[points.dtype.fields[n][0]],
            count=1,
        )
        for n in points.dtype.names
    ]
    stamp = msg_types["Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    raw = (
        np.frombuffer(points.tobytes(), dtype=np.uint8)
        if data is None
        else np.frombuffer(data, dtype=np.uint8)
    )
    return msg_types["PointCloud2"](
        header=msg_types["Header"](**({"seq": 0} if ros1 else {}), stamp=stamp, frame_id=frame_id),
        height=1,
        width=points.size,
        fields=fields,
        is_bigendian=False,
        point_step=points.dtype.itemsize,
        row_step=points.dtype.itemsize * points.size,
        data=raw,
        is_dense=True,
    )


def odometry(store, stamp_ns: int, x_m: float):
    """A nav_msgs/Odometry of ``base_link`` in ``odom`` at ``stamp_ns``: ``x_m`` along ROS x, facing it."""
    t = store.types
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=x_m, y=0.0, z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    zero = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    stamp = t["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    return t["nav_msgs/msg/Odometry"](
        header=t["std_msgs/msg/Header"](stamp=stamp, frame_id="odom"),
        child_frame_id="base_link",
        pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
        ),
    )


# oracle grid (no detector needed): a 1.5 m pit 12 m on and 6 m left of the start line (a steering
# of 0.18 rad, R = 15 m, runs through it), a pit on the line 30 m on, a rock on the line 8 m on
PITS_BESIDE_AND_AHEAD_SCENE = """
name = "pits_beside_and_ahead"
[terrain.course]
length_m = 50.0
[[obstacles]]
kind = "pit"
length_m = 1.5
width_m = 1.5
station_m = 12.0
lateral_m = -6.0
[[obstacles]]
kind = "pit"
length_m = 1.0
width_m = 2.5
station_m = 30.0
[[positive_obstacles]]
kind = "rock"
station_m = 8.0
lateral_m = 0.0
[observation]
source = "oracle"
"""


def write_vetoes_csv(path, judged) -> None:
    """A hand-made campaign ``vetoes.csv``: one row per (episode, filter label, kind, error_m[,
    onset]) of ``judged`` (onset: 1 for a veto unless given), the other cells fixed (d 8 m, R 9 m
    at 5 m/s, truth d - error)."""
    from negobs_gym.eval.campaign import format_row
    from negobs_gym.eval.vetoes import VETO_COLUMNS

    def row(key, label, kind, error, onset=None):
        onset = kind == "veto" if onset is None else onset
        fixed = (5.0, 9.0, 8.0, 8.0 - error, error, "negative", 0, 0, 1.0, 0.0, -1.0, 0.0)
        return format_row([key, label, 0, 1, kind, onset, *fixed])

    lines = [row(*judgement) for judgement in judged]
    path.write_text(",".join(VETO_COLUMNS) + "\n" + "\n".join(lines) + "\n")
