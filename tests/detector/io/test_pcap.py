"""Raw Velodyne pcap: real HDL-32E captures, and captures cut, emptied or replaced by junk."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.detector.io import ScanSetup, read_recording
from negobs_gym.detector.io.pcap import read_pcap, truncated_at
from negobs_gym.errors import ScanError

from .conftest import HDL32E_A, HDL32E_B

pytest.importorskip("velodyne_decoder")


def test_real_capture_is_a_sequence_of_ring_scans():
    frames = list(read_recording(HDL32E_A, ScanSetup(azimuth_resolution_deg=0.16)))
    assert [f.index for f in frames] == [0, 1]
    assert [f.n_points for f in frames] == [18154, 1425]
    scan = frames[0].scan
    assert frames[0].ring_source == "ring_field" and scan.shape == (32, 2250)
    # rows at the measured elevations: the HDL-32E's -30.67..+10.67 deg in 4/3 deg steps
    np.testing.assert_allclose(np.degrees(scan.elevation_rad), np.linspace(-30.67, 10.67, 32), atol=0.25)
    assert frames[1].scan.timestamp_s > scan.timestamp_s


def test_binned_ranges_are_the_recorded_ranges(hdl32e_points):
    (scan,) = list(read_pcap(HDL32E_B, ScanSetup(azimuth_resolution_deg=0.16)))
    p = hdl32e_points
    recorded = np.sort(np.linalg.norm(np.column_stack([p["x"], p["y"], p["z"]]).astype(float), axis=1))
    binned = np.sort(scan.ranges_m[scan.valid])
    assert binned.size == recorded.size  # one point per (ring, 0.16 deg) cell on this capture
    np.testing.assert_allclose(binned, recorded, rtol=1e-6)


def test_truncated_capture_reads_the_whole_packets_and_warns(tmp_path, caplog):
    data = HDL32E_B.read_bytes()
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(data[: len(data) // 2 + 77])
    assert truncated_at(str(cut)) is not None and truncated_at(str(HDL32E_B)) is None
    (frame,) = list(read_recording(cut, ScanSetup()))
    assert 0 < frame.n_points < 30596
    assert "ends inside a packet" in caplog.text


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"", "file is empty"),
        (bytes(range(256)) * 10, "not a readable Velodyne pcap"),
        (None, "no Velodyne data"),
    ],
)
def test_bad_captures_raise_scan_error(tmp_path, content, match):
    bad = tmp_path / "bad.pcap"
    bad.write_bytes(HDL32E_B.read_bytes()[:24] if content is None else content)  # None: header only
    with pytest.raises(ScanError, match=match):
        list(read_recording(bad, ScanSetup()))
