"""``negobs detect --deskew``: a revolution scanned while driving, made one snapshot again.

The bag is synthetic: an upright HDL-64 at 2.2 m, driving at 25 km/h (7 m/s) towards a 2 m wide
pit, each revolution (0.1 s) starting straight ahead and turning clockwise, so the pit's right half
is scanned first and its left half 0.1 s (0.7 m) later; each point carries its firing time after
the header stamp in a ``time`` field, as velodyne_pointcloud writes it; odometry at 50 Hz.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.detector.loaders import sensor_to_ros_frame
from negobs_gym.detector.synthetic import HDL64_ELEVATION_DEG, Hole, synthetic_scan
from tests.helpers import odometry, pointcloud2

SPEED_MPS, NEAR_M, FRAMES, PERIOD_S = 7.0, 9.0, 3, 0.1
START_NS = 10**9
COLUMNS, GROUPS = 4000, 100  # the revolution cast in 100 slices of 1 ms
ORIGIN = np.array([0.0, 0.0, 2.2])  # the sensor, upright above the vehicle origin
A_BEFORE_M = 0.3  # a pair's A, the last ground return before the pit: up to a ring gap (0.28 m at 9 m)


def _near(time_s: float) -> float:
    return NEAR_M - SPEED_MPS * time_s


def _revolution(start_s: float) -> np.ndarray:
    """One revolution from ``start_s`` (after the first cloud), in the ROS sensor frame, with each
    return's ring and its time after ``start_s``."""
    azimuth = np.linspace(-np.pi, np.pi, COLUMNS, endpoint=False) + np.pi / COLUMNS
    offset = (azimuth % (2 * np.pi)) / (2 * np.pi) * PERIOD_S  # from straight ahead, clockwise
    elevation = np.radians(HDL64_ELEVATION_DEG)
    parts = []
    for columns in np.array_split(np.argsort(offset), GROUPS):
        columns = np.sort(columns)
        fired_s = start_s + offset[columns].mean()
        hole = Hole.ahead(_near(fired_s), 2.0, 1.0, 0.8)
        scan = synthetic_scan("hdl64", elevation, azimuth[columns], np.eye(3), ORIGIN, [hole])
        p = scan.points_sensor[scan.valid]  # X right, Y forward -> ROS x forward, y left
        ring = np.broadcast_to(np.arange(scan.shape[0])[:, None], scan.shape)[scan.valid]
        time = np.broadcast_to(offset[columns][None, :], scan.shape)[scan.valid]
        parts.append(np.column_stack([sensor_to_ros_frame(p), ring, time]))
    rows = np.concatenate(parts)
    fields = [(n, "<f4") for n in "xyz"] + [("intensity", "<f4"), ("ring", "<u2"), ("time", "<f4")]
    points = np.zeros(len(rows), dtype=fields)
    for k, name in enumerate(("x", "y", "z", "ring", "time")):
        points[name] = rows[:, k]
    return points


@pytest.fixture(scope="module")
def skewed_bag(tmp_path_factory) -> Path:
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from tests.helpers import POINTFIELD_CODES

    POINTFIELD_CODES.setdefault(np.dtype("<f4"), 7)
    store = get_typestore(Stores.ROS2_HUMBLE)
    bag = tmp_path_factory.mktemp("skewed") / "skewed"
    messages = []
    with Writer(bag, version=9) as writer:
        clouds = writer.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=store)
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        for k in range(FRAMES):
            stamp = START_NS + int(k * PERIOD_S * 1e9)  # the revolution's start, as the header stamp
            msg = pointcloud2(store, _revolution(k * PERIOD_S), stamp)
            messages.append((stamp, clouds, store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")))
        for j in range(-5, 5 * FRAMES + 10):
            stamp = START_NS + j * 20_000_000
            msg = odometry(store, stamp, SPEED_MPS * (stamp - START_NS) * 1e-9)
            messages.append((stamp, odom, store.serialize_cdr(msg, "nav_msgs/msg/Odometry")))
        for stamp, connection, raw in sorted(messages, key=lambda m: m[0]):
            writer.write(connection, stamp, raw)
    return bag


def _records(bag: Path, out: Path, *extra: str) -> list[dict]:
    args = ["-q", "detect", str(bag), "--no-png", "--out", str(out), "--poses-topic", "/odom", *extra]
    assert main(args) == 0
    return [json.loads((out / f"{k:05d}_skewed_{k:04d}.json").read_text()) for k in range(FRAMES)]


def _near_edge_by_side(record: dict) -> tuple[np.ndarray, np.ndarray]:
    """This frame's pairs' A points ahead [m], of the pit's right half and of its left half."""
    a = np.array(record["frame_pairs"]["hdl64"]["a_m"])
    return a[a[:, 0] > 0.05, 1], a[a[:, 0] < -0.05, 1]


def test_deskewed_revolutions_see_the_pit_edge_straight(skewed_bag, tmp_path) -> None:
    deskewed = _records(skewed_bag, tmp_path / "deskewed", "--deskew")
    skewed = _records(skewed_bag, tmp_path / "skewed")
    for k in range(FRAMES):
        near = _near(k * PERIOD_S)  # at the cloud's stamp, the revolution's start
        right, left = _near_edge_by_side(deskewed[k])
        assert right.size > 10 and left.size > 10
        for side in (right, left):
            assert np.all((side > near - A_BEFORE_M) & (side <= near + 0.02)), (k, side.min(), side.max())
        # skewed, the left half was scanned up to 0.1 s later, up to 0.7 m nearer
        right, left = _near_edge_by_side(skewed[k])
        assert np.median(right) - np.median(left) > 0.5
        # deskewing moves what the features found, not the features: as many pairs either way
        assert deskewed[k]["n_frame_pairs"] >= 0.9 * skewed[k]["n_frame_pairs"]
        assert deskewed[k]["deskewed"] and not skewed[k]["deskewed"]
    # the same cloud named as a rig of one LiDAR (--cloud) is deskewed alike
    rig = _records(skewed_bag, tmp_path / "rig", "--deskew", "--cloud", "/points:hdl64")
    assert [r["frame_pairs"] for r in rig] == [r["frame_pairs"] for r in deskewed]
    # the pit's one outline, confirmed at the third frame, starts at its edge
    (obstacle,) = deskewed[2]["obstacles"]
    assert _near(0.2) - A_BEFORE_M < min(y for _, y in obstacle["outline_xy_m"]) <= _near(0.2)


def test_deskew_needs_timed_poses_and_point_times(skewed_bag, tmp_path, capsys) -> None:
    out = str(tmp_path / "o")
    assert main(["detect", str(skewed_bag), "--out", out, "--deskew"]) == 2
    assert "--deskew needs the vehicle's motion in time" in capsys.readouterr().err
    scan = tmp_path / "f.bin"
    np.zeros((10, 4), dtype=np.float32).tofile(scan)
    assert main(["detect", str(scan), "--out", out, "--deskew", "--poses-topic", "/odom"]) == 2
    assert "not a readable ROS bag" in capsys.readouterr().err
