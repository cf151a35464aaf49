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


def test_set_rings_reaches_the_point_order_rule_and_is_recorded(tmp_path, capsys):
    """``--set rings.*`` sets loaders.PointOrderConfig: cuts asked to step 50 laser spacings in
    elevation refuse KITTI's order (the warning names the file), config.json records the value, and
    a threshold the config refuses exits 2 naming it."""
    cloud, _ = _kitti_cloud("raw", seed=2)
    path = tmp_path / "0000000002.bin"
    cloud.tofile(path)
    args = ["detect", str(path), "--height", "1.73", "--no-png"]
    out = tmp_path / "strict"
    assert main([*args, "--out", str(out), "--set", "rings.min_cut_step_spacings=50"]) == 0
    (frame,) = sorted(out.glob("0000*_0000000002_*.json"))
    assert json.loads(frame.read_text())["ring_source"] == "elevation_table"
    warned = [line for line in capsys.readouterr().err.splitlines() if "elevation-table" in line]
    assert len(warned) == 1 and str(path) in warned[0] and "between lasers" in warned[0]
    assert json.loads((out / "config.json").read_text())["rings"]["min_cut_step_spacings"] == 50.0
    assert main([*args, "--out", str(tmp_path / "bad"), "--set", "rings.back_step_deg=200"]) == 2
    assert "rings.back_step_deg=200: back_step_deg: must be in (0, 180)" in capsys.readouterr().err
