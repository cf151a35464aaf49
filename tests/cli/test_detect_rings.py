"""``negobs detect`` on generated KITTI-layout .bin files: rings from the point order, and the
elevation-table fallback announced on stderr with the file's name."""

from __future__ import annotations

import json

import numpy as np

from negobs_gym.cli import main
from tests.detector.io.test_kitti_layout import _kitti_cloud


def test_kitti_order_reads_rings_from_the_point_order_without_warning(tmp_path, capsys):
    cloud, laser = _kitti_cloud("object", seed=1)
    path = tmp_path / "000001.bin"
    cloud.tofile(path)
    out = tmp_path / "out"
    assert main(["detect", str(path), "--height", "1.73", "--out", str(out), "--no-png"]) == 0
    (frame,) = sorted(out.glob("0000*_000001_*.json"))
    record = json.loads(frame.read_text())
    assert record["ring_source"] == "point_order"
    assert record["scan_shape"][0] == np.unique(laser).size
    assert "elevation-table" not in capsys.readouterr().err


def test_fallback_to_the_table_is_a_warning_on_stderr_naming_the_file(tmp_path, capsys):
    cloud, _ = _kitti_cloud("object", seed=1)
    path = tmp_path / "shuffled.bin"
    cloud[np.random.default_rng(0).permutation(len(cloud))].tofile(path)
    out = tmp_path / "out"
    assert main(["detect", str(path), "--height", "1.73", "--out", str(out), "--no-png"]) == 0
    (frame,) = sorted(out.glob("0000*_shuffled_*.json"))
    assert json.loads(frame.read_text())["ring_source"] == "elevation_table"
    warned = [line for line in capsys.readouterr().err.splitlines() if "elevation-table" in line]
    assert len(warned) == 1 and str(path) in warned[0]
