"""Headerless float32 binaries (KITTI-style xyzi, xyzir) made from the real HDL-32E frame; dispatch."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.detector.io import ScanSetup, fields_to_scan, read_bin, read_recording
from negobs_gym.detector.loaders import (
    assign_rings,
    load_kitti_bin,
    load_ring_bin,
    recover_rings,
    ros_to_sensor_frame,
)
from negobs_gym.errors import ConfigError, ScanError

HDL32E_TABLE = tuple(np.radians(np.linspace(-30.67, 10.67, 32)))
SETUP = ScanSetup(azimuth_resolution_deg=0.16, elevation_rad=HDL32E_TABLE)


def _laser_order(p):
    """Indices of the points laser by laser, each laser's sweep clockwise from behind (as KITTI)."""
    return np.lexsort((np.arctan2(-p["y"], p["x"]), p["ring"]))


def _xyzi(p, order=None):
    cols = np.column_stack([p[k] for k in ("x", "y", "z", "intensity")]).astype(np.float32)
    return cols if order is None else cols[order]


def test_kitti_order_recovers_rings_where_another_units_table_fails(tmp_path, hdl32e_points):
    p = hdl32e_points
    order = _laser_order(p)
    path = tmp_path / "000000.bin"
    _xyzi(p, order).tofile(path)
    frame = read_bin(path, SETUP)
    assert frame.ring_source == "point_order"
    truth, _ = fields_to_scan({k: p[k] for k in ("x", "y", "z", "intensity", "ring")}, SETUP, source="truth")
    np.testing.assert_array_equal(frame.scan.ranges_m, truth.ranges_m)
    # a table more than half a laser spacing off this unit (0.67 deg here, 0.2 deg on an HDL-64E)
    # mis-rings points when used per point; the point order does not need the table to be right
    xyz = ros_to_sensor_frame(_xyzi(p, order)[:, :3])
    shifted = np.asarray(HDL32E_TABLE) + np.radians(0.8)
    by_table = assign_rings(xyz[np.random.default_rng(0).permutation(len(xyz))], shifted)
    assert by_table.source == "elevation_table"
    wrong = (recover_rings(xyz, shifted) != p["ring"][order]).mean()
    assert wrong > 0.5
    by_order = assign_rings(xyz, shifted)
    assert by_order.source == "point_order"
    _, first = np.unique(by_order.ring, return_index=True)
    # same partition of the points into lasers as the decoder's ring field
    assert len(first) == 32 and (np.diff(p["ring"][order][np.sort(first)]) > 0).all()


def test_firing_order_and_shuffled_clouds_fall_back_to_the_table(tmp_path, hdl32e_points):
    p = hdl32e_points
    for name, order in (
        ("firing", np.arange(p.size)),
        ("shuffled", np.random.default_rng(1).permutation(p.size)),
    ):
        path = tmp_path / f"{name}.bin"
        _xyzi(p, order).tofile(path)
        assert read_bin(path, SETUP).ring_source == "elevation_table", name
    assert load_kitti_bin(path, np.asarray(HDL32E_TABLE), sensor="hdl32").shape[0] == 32


def test_ring_binary(tmp_path, hdl32e_points):
    p = hdl32e_points
    cloud = np.column_stack([_xyzi(p), p["ring"].astype(np.float32)])
    path = tmp_path / "frame.bin"
    cloud.tofile(path)
    frame = next(read_recording(path, SETUP, bin_layout="xyzir"))
    assert frame.ring_source == "ring_field" and frame.scan.shape == (32, 2250)
    assert frame.scan.valid.sum() == p.size
    np.testing.assert_array_equal(
        load_ring_bin(path, azimuth_resolution_deg=0.16).ranges_m, frame.scan.ranges_m
    )


def test_bad_binaries(tmp_path, hdl32e_points):
    p = hdl32e_points
    good = _xyzi(p)
    cases = {
        "empty.bin": (np.empty(0, np.float32), "file is empty", "xyzi"),
        "cut.bin": (good.reshape(-1)[:-1], "not a multiple of 4", "xyzi"),
        "nan.bin": (
            np.where(np.arange(good.size).reshape(good.shape) == 7, np.nan, good),
            "NaN or inf",
            "xyzi",
        ),
        # a KITTI xyzi file read as xyzir: 4 x 5 points fit, the "ring" column holds intensities/coords
        "kitti_as_ring.bin": (good[:20], "ring", "xyzir"),
    }
    for name, (data, match, layout) in cases.items():
        path = tmp_path / name
        np.asarray(data, np.float32).tofile(path)
        with pytest.raises(ScanError, match=match):
            read_bin(path, SETUP, layout)
    with pytest.raises(ScanError, match="layout"):
        read_bin(tmp_path / "cut.bin", SETUP, "xyz")  # type: ignore[arg-type]


def test_dispatch_and_setup_errors(tmp_path):
    with pytest.raises(ScanError, match="no such file"):
        list(read_recording(tmp_path / "missing.bin", SETUP))
    (tmp_path / "cloud.las").write_bytes(b"LASF")
    with pytest.raises(ScanError, match="unknown recording type"):
        list(read_recording(tmp_path / "cloud.las", SETUP))
    with pytest.raises(ScanError, match="per-point times are read from bags and pcap captures only"):
        list(read_recording(tmp_path / "cloud.las", SETUP, point_times=True))
    with pytest.raises(ConfigError, match="azimuth_resolution_deg"):
        ScanSetup(azimuth_resolution_deg=0.0)
    with pytest.raises(ConfigError, match="translation_m"):
        ScanSetup(translation_m=(0.0, 0.0, float("nan")))


def test_io_imports_no_simulator_and_no_optional_reader_for_bins(tmp_path):
    import subprocess
    import sys

    path = tmp_path / "frame.bin"
    np.array([[1.0, 2.0, -1.0, 0.5, 0.0], [2.0, 1.0, -1.0, 0.5, 1.0]], np.float32).tofile(path)
    code = (
        "import sys\n"
        "from negobs_gym.detector.io import ScanSetup, read_bin\n"
        f"read_bin({str(path)!r}, ScanSetup(), 'xyzir')\n"
        "bad = ('pybullet', 'gymnasium', 'matplotlib', 'negobs_gym.sim', 'negobs_gym.sensors',"
        " 'pypcd4', 'rosbags', 'velodyne_decoder')\n"
        "print([m for m in bad if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize(
    ("module", "package", "name"),
    [
        ("pypcd4", "pypcd4", "x.pcd"),
        ("velodyne_decoder", "velodyne-decoder", "x.pcap"),
        ("rosbags.highlevel", "rosbags", "x.bag"),
    ],
)
def test_missing_extra_names_the_package(tmp_path, monkeypatch, module, package, name):
    import sys

    from negobs_gym.errors import MissingDependencyError

    path = tmp_path / name
    path.write_bytes(b"\0" * 64)
    monkeypatch.setitem(sys.modules, module, None)  # importing it now raises ImportError
    with pytest.raises(MissingDependencyError, match=rf"pip install {package}") as info:
        list(read_recording(path, SETUP))
    assert "negobs_gym[real]" in str(info.value)
