"""When each column of a recorded cloud was fired, from its points' time field."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from negobs_gym.detector.io import ScanSetup
from negobs_gym.detector.io.setup import column_time_offsets
from negobs_gym.errors import ScanError

# four columns by this package's azimuth, clockwise from ahead: [-180, -90) behind left, [-90, 0)
# ahead left, [0, 90) ahead right, [90, 180) behind right (as cloud_to_scan bins them)
SETUP = ScanSetup(azimuth_resolution_deg=90.0)
# ROS frame (x forward, y left): ahead right, ahead left, behind right, ahead right again
XYZ = {"x": np.array([5.0, 5.0, -5.0, 6.0]), "y": np.array([-5.0, 5.0, -5.0, -4.0]), "z": np.zeros(4)}


def test_each_column_takes_the_mean_time_of_its_returns() -> None:
    seconds = column_time_offsets(
        {**XYZ, "time": np.float32([0.01, 0.03, 0.08, 0.02])}, SETUP, source="s", stamp_s=5.0
    )
    np.testing.assert_allclose(seconds, [np.nan, 0.03, 0.015, 0.08], atol=1e-7)
    # integers are nanoseconds (Ouster t, Livox offset_time), after the stamp
    ns = column_time_offsets({**XYZ, "t": np.uint32([1e7, 3e7, 8e7, 2e7])}, SETUP, source="s", stamp_s=5.0)
    np.testing.assert_allclose(ns, seconds, atol=1e-7)
    # times since the epoch (Hesai timestamp) are made relative to the stamp
    stamp = 1_700_000_000.0
    absolute = {**XYZ, "timestamp": stamp + np.array([0.01, 0.03, 0.08, 0.02])}
    np.testing.assert_allclose(
        column_time_offsets(absolute, SETUP, source="s", stamp_s=stamp), seconds, atol=1e-6
    )


def test_cropped_columns_take_the_times_of_their_columns() -> None:
    """With ``crop_columns`` the times are those of the scan's columns: from the first to the last
    with a return (here ahead left to behind right)."""
    fields = {**XYZ, "time": np.float32([0.01, 0.03, 0.08, 0.02])}
    cropped = dataclasses.replace(SETUP, crop_columns=True)
    seconds = column_time_offsets(fields, cropped, source="s", stamp_s=5.0)
    np.testing.assert_allclose(seconds, [0.03, 0.015, 0.08], atol=1e-7)
    scan = cropped.scan(np.column_stack([-XYZ["y"], XYZ["x"], XYZ["z"]]), np.zeros(4), np.zeros(1), None, 0.0)
    assert scan.shape == (1, 3)


def test_a_cloud_without_a_finite_time_field_is_refused_by_name() -> None:
    with pytest.raises(ScanError, match="c: no per-point time field"):
        column_time_offsets(XYZ, SETUP, source="c", stamp_s=0.0)
    with pytest.raises(ScanError, match="time field holds a value that is not finite"):
        column_time_offsets(
            {**XYZ, "time": np.array([0.0, np.nan, 0.0, 0.0])}, SETUP, source="c", stamp_s=0.0
        )


def test_a_real_hdl32e_revolution_fires_clockwise(hdl32e_points) -> None:
    fields = {k: hdl32e_points[k] for k in ("x", "y", "z", "time")}
    seconds = column_time_offsets(fields, ScanSetup(azimuth_resolution_deg=0.16), source="real", stamp_s=0.0)
    fired = seconds[~np.isnan(seconds)]
    # this package's azimuth runs clockwise from ahead, as the sensor spins: later columns fire later,
    # but at the one cut where the revolution starts
    steps = np.diff(fired)
    assert (steps > 0).mean() > 0.99 and (steps < -0.04).sum() <= 1
    assert 0.04 < fired.max() - fired.min() <= 0.1  # at most one revolution (10-20 Hz)
