"""PCD files: the real VLP-32C file (ring field "channel"), and PCDs written from the real HDL-32E
points with another field set, NaN, inf, cut or empty."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from negobs_gym.detector.io import ScanSetup, fields_to_scan, read_recording
from negobs_gym.detector.io.pcd import load_pcd
from negobs_gym.errors import MissingDependencyError, ScanError

from .conftest import VLP32C_PCD

pypcd4 = pytest.importorskip("pypcd4")


def _write_pcd(path, fields: dict, encoding="binary"):
    names = list(fields)
    cloud = pypcd4.PointCloud.from_points(
        [np.asarray(fields[k]) for k in names], names, [fields[k].dtype for k in names]
    )
    cloud.save(path, encoding=pypcd4.Encoding(encoding))
    return path


def _as_fields(points, names=("x", "y", "z", "intensity", "ring")):
    return {k: np.ascontiguousarray(points[k]) for k in names}


def test_real_vlp32c_file_rows_are_its_channels_by_elevation():
    frame = next(read_recording(VLP32C_PCD, ScanSetup(azimuth_resolution_deg=0.2)))
    scan = frame.scan
    assert frame.ring_source == "ring_field" and frame.n_points == 26216
    assert scan.shape == (32, 1800)
    assert scan.valid.sum() >= 0.98 * 26216  # 1.5 % share a 0.2 deg cell with another; the nearest stays
    assert (np.diff(scan.elevation_rad) > 0).all()  # interleaved channel ids sorted into elevation order
    data = pypcd4.PointCloud.from_path(VLP32C_PCD).pc_data
    table = np.sort([np.median(data["elevation"][data["channel"] == c]) for c in np.unique(data["channel"])])
    # measured from the points vs the driver's per-channel elevation: sub-degree (sensor offsets)
    np.testing.assert_allclose(np.degrees(scan.elevation_rad), np.degrees(table), atol=1.0)


@pytest.mark.parametrize("encoding", ["ascii", "binary", "binary_compressed"])
def test_written_pcd_gives_the_same_scan_as_the_points(tmp_path, hdl32e_points, encoding):
    fields = _as_fields(hdl32e_points)
    path = _write_pcd(tmp_path / "frame.pcd", fields, encoding)
    setup = ScanSetup(azimuth_resolution_deg=0.16, translation_m=(0.0, 0.0, 2.3))
    scan = load_pcd(path, setup)
    direct, _ = fields_to_scan(fields, setup, source="points")
    np.testing.assert_allclose(scan.ranges_m, direct.ranges_m, equal_nan=True, rtol=1e-6)
    np.testing.assert_allclose(scan.translation_m, [0.0, 0.0, 2.3])


def test_pcd_without_ring_in_laser_order_recovers_the_rings(tmp_path, hdl32e_points):
    p = hdl32e_points
    order = np.lexsort((np.arctan2(-p["y"], p["x"]), p["ring"]))  # laser by laser, each sweep clockwise
    fields = {k: np.ascontiguousarray(p[k][order]) for k in ("x", "y", "z", "intensity")}
    table = tuple(np.radians(np.linspace(-30.67, 10.67, 32)))
    frame = next(read_recording(_write_pcd(tmp_path / "noring.pcd", fields), ScanSetup(elevation_rad=table)))
    assert frame.ring_source == "point_order"
    truth, _ = fields_to_scan(_as_fields(p), ScanSetup(), source="truth")
    np.testing.assert_array_equal(frame.scan.valid, truth.valid)


def test_pcd_without_ring_or_table_is_refused(tmp_path, hdl32e_points):
    rng = np.random.default_rng(0)
    p = hdl32e_points[rng.permutation(hdl32e_points.size)]  # no laser order either
    path = _write_pcd(tmp_path / "noring.pcd", _as_fields(p, ("x", "y", "z", "intensity")))
    with pytest.raises(ScanError, match="no ring field"):
        list(read_recording(path, ScanSetup()))


def test_wrong_field_set_nan_and_inf(tmp_path, hdl32e_points):
    p = hdl32e_points
    with pytest.raises(ScanError, match="no z field"):
        list(
            read_recording(
                _write_pcd(tmp_path / "xy.pcd", _as_fields(p, ("x", "y", "intensity", "ring"))), ScanSetup()
            )
        )
    fields = _as_fields(p)
    fields["x"] = fields["x"].copy()
    fields["x"][::2] = np.nan  # organised clouds mark missing returns so: dropped
    frame = next(
        read_recording(_write_pcd(tmp_path / "half.pcd", fields), ScanSetup(azimuth_resolution_deg=0.16))
    )
    assert frame.scan.valid.sum() == p.size - (p.size + 1) // 2
    half_ring = dict(fields, ring=fields["ring"].astype(np.float32) + 0.5)
    with pytest.raises(ScanError, match="ring field must hold integers"):
        list(read_recording(_write_pcd(tmp_path / "halfring.pcd", half_ring), ScanSetup()))
    fields["x"][:] = np.nan
    with pytest.raises(ScanError, match="no finite point"):
        list(read_recording(_write_pcd(tmp_path / "nan.pcd", fields), ScanSetup()))
    fields["x"][:] = np.inf
    with pytest.raises(ScanError, match="inf"):
        list(read_recording(_write_pcd(tmp_path / "inf.pcd", fields), ScanSetup()))


@pytest.mark.parametrize(
    ("cut", "match"), [(0, "file is empty"), (300, "not a readable PCD"), (0.5, "not a readable PCD")]
)
def test_cut_or_empty_pcd_raises_scan_error(tmp_path, cut, match):
    data = VLP32C_PCD.read_bytes()
    bad = tmp_path / "bad.pcd"
    bad.write_bytes(data[: int(cut * len(data)) if isinstance(cut, float) else cut])
    with pytest.raises(ScanError, match=match):
        list(read_recording(bad, ScanSetup()))


def test_missing_pypcd4_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "pypcd4", None)  # import pypcd4 now raises ImportError
    with pytest.raises(MissingDependencyError, match=r"pip install pypcd4.*|negobs_gym\[real\]"):
        list(read_recording(VLP32C_PCD, ScanSetup()))
