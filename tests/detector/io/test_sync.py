"""Several topics' clouds grouped into detector updates, and a cloud brought to the lead's time."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io import PoseTrack, RecordedFrame
from negobs_gym.detector.io.sync import scan_at_time, synchronise
from negobs_gym.detector.synthetic import Hole, hdl32_side_scan
from negobs_gym.errors import ScanError


def _frame(time_s: float, index: int = 0) -> RecordedFrame:
    scan = StructuredScan("s", np.ones((1, 2)), np.array([0.0, 1.0]), np.array([0.0]), timestamp_s=time_s)
    return RecordedFrame(scan, "bag", index, "ring_field", 2)


def _stream(times: dict[str, list[float]]) -> list[tuple[str, RecordedFrame]]:
    """Every topic's clouds merged by time, as a recording holds them."""
    clouds = [(t, topic, _frame(t, i)) for topic, ts in times.items() for i, t in enumerate(ts)]
    return [(topic, frame) for _, topic, frame in sorted(clouds, key=lambda c: c[0])]


def _times(update) -> dict[str, float]:
    return {topic: round(frame.scan.timestamp_s, 6) for topic, frame in update.clouds.items()}


def test_each_lead_cloud_takes_every_topics_nearest_unused_cloud_within_the_window() -> None:
    lead = [0.0, 0.1, 0.2, 0.3, 0.4]
    left = [t - 0.04 for t in lead]
    right = [0.03, 0.13, 0.33, 0.43]  # the right sensor dropped its cloud at 0.23
    stream = _stream({"top": lead, "left": left, "right": right})
    updates = list(synchronise(stream, "top", ["left", "right"]))
    assert [u.time_s for u in updates] == lead
    assert [_times(u) for u in updates] == [
        {"top": 0.0, "left": -0.04, "right": 0.03},
        {"top": 0.1, "left": 0.06, "right": 0.13},
        {"top": 0.2, "left": 0.16},  # 0.13 went to 0.1; 0.33 is 0.13 s away
        {"top": 0.3, "left": 0.26, "right": 0.33},
        {"top": 0.4, "left": 0.36, "right": 0.43},
    ]
    # a one-revolution gap is still taken; a narrower window leaves the sensors out
    late = list(synchronise(_stream({"top": [0.0], "left": [0.1]}), "top", ["left"]))
    assert _times(late[0]) == {"top": 0.0, "left": 0.1}
    narrow = synchronise(_stream({"top": lead, "left": left}), "top", ["left"], window_s=0.02)
    assert all(set(u.clouds) == {"top"} for u in narrow)


def test_updates_stream_and_a_quiet_topic_holds_them_back_only_by_the_lag() -> None:
    lead = [k * 0.1 for k in range(40)]
    stream = _stream({"top": lead, "left": [0.01, 0.11]})  # the left sensor stops after 0.11 s
    consumed = 0

    def counted():
        nonlocal consumed
        for item in stream:
            consumed += 1
            yield item

    updates = synchronise(counted(), "top", ["left"], window_s=0.1, lag_s=1.0)
    first = next(updates)
    assert _times(first) == {"top": 0.0, "left": 0.01}
    # the first update waits for the left's cloud at 0.11 (past 0.0 + window) and no longer
    assert consumed == 4
    second = next(updates)
    assert _times(second) == {"top": 0.1, "left": 0.11}
    # with the left gone, the third waits for a lead cloud 1.1 s later, not for the end
    third = next(updates)
    assert _times(third) == {"top": 0.2} and consumed < len(stream)
    assert len(list(updates)) == len(lead) - 3


def test_synchronise_refuses_a_topic_twice_and_a_bad_window() -> None:
    with pytest.raises(ScanError, match="each topic once"):
        list(synchronise([], "top", ["top"]))
    with pytest.raises(ScanError, match="each topic once"):
        list(synchronise([], "top", ["left", "left"]))
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ScanError, match="window_s must be finite and >= 0"):
            list(synchronise([], "top", ["left"], window_s=bad))
    with pytest.raises(ScanError, match="lag_s"):
        list(synchronise([], "top", ["left"], lag_s=-1.0))


def test_a_cloud_brought_to_the_lead_time_lands_where_the_vehicle_then_sees_it() -> None:
    # the vehicle drives 7 m/s along ROS x while turning 20 deg/s; the side cloud is 40 ms older
    times = np.array([0.9, 1.0, 1.1])
    yaw = np.radians(20.0) * (times - 1.0)
    track = PoseTrack(
        times,
        np.column_stack([7.0 * (times - 1.0), np.zeros(3), np.zeros(3)]),
        Rotation.from_euler("z", yaw[:, None]).as_quat(),
    )
    scan = hdl32_side_scan([Hole.ahead(8.0, 1.0, 1.0, 0.8)], side="left")
    scan = StructuredScan(**{**scan.__dict__, "timestamp_s": 0.96})
    moved = scan_at_time(scan, track, 1.0)
    then, now = track.at(0.96), track.at(1.0)
    expected = now.to_vehicle(then.to_world(scan.points_vehicle))
    np.testing.assert_allclose(moved.points_vehicle, expected, atol=1e-9, equal_nan=True)
    np.testing.assert_array_equal(moved.ranges_m, scan.ranges_m)
    assert moved.timestamp_s == 0.96
    # the scan's geometry stays as recorded (the features read it so); every column carries the
    # vehicle's motion: the sensor fired 0.28 m farther back (1 cm less by the turn), turned 0.8
    # deg clockwise
    np.testing.assert_array_equal(moved.rotation, scan.rotation)
    np.testing.assert_array_equal(moved.translation_m, scan.translation_m)
    assert (moved.column_motion == moved.column_motion[0]).all()
    origin = moved.origins_vehicle(np.array([0]))[0]
    assert origin[1] == pytest.approx(scan.translation_m[1] - 0.28, abs=0.02)
    turn = Rotation.from_matrix(moved.column_motion[0, :, :3]).as_rotvec()
    np.testing.assert_allclose(np.degrees(turn), [0.0, 0.0, -0.8], atol=1e-9)
    # at its own time nothing moves
    same = scan_at_time(scan, track, 0.96)
    np.testing.assert_allclose(same.points_vehicle, scan.points_vehicle, atol=1e-12, equal_nan=True)


def test_a_deskewed_scan_moves_each_column_by_the_vehicles_motion_since_it_fired() -> None:
    times = np.array([0.9, 1.0, 1.1, 1.2])
    track = PoseTrack(
        times,
        np.column_stack([7.0 * (times - 1.0), np.zeros(4), np.zeros(4)]),
        Rotation.from_euler("z", np.radians(20.0) * (times[:, None] - 1.0)).as_quat(),
    )
    scan = hdl32_side_scan([Hole.ahead(8.0, 1.0, 1.0, 0.8)], side="left")
    scan = StructuredScan(**{**scan.__dict__, "timestamp_s": 1.0})
    fired = np.linspace(0.0, 0.1, scan.shape[1], endpoint=False)  # one revolution after its stamp
    fired[5] = np.nan  # a column without returns: taken at the stamp
    moved = scan_at_time(scan, track, 1.05, column_time_s=fired)
    now = track.at(1.05)
    for column in (0, 5, 700, 1500, scan.shape[1] - 1):
        then = track.at(1.0 + np.nan_to_num(fired[column]))
        expected = now.to_vehicle(then.to_world(scan.points_vehicle[:, column]))
        np.testing.assert_allclose(moved.points_vehicle[:, column], expected, atol=1e-4, equal_nan=True)
        np.testing.assert_allclose(
            moved.origins_vehicle([column])[0], now.to_vehicle(then.to_world(scan.translation_m)), atol=1e-4
        )
    # the range image and the mounting as recorded: the features read the scan the sensor saw
    np.testing.assert_array_equal(moved.ranges_m, scan.ranges_m)
    np.testing.assert_array_equal(moved.rotation, scan.rotation)
    with pytest.raises(ScanError, match="column_time_s has shape"):
        scan_at_time(scan, track, 1.05, column_time_s=fired[:-1])
