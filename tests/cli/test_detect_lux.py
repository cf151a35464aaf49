"""``negobs detect --sensor lux``: paper T's traversable-region detector on recorded 4-layer scans
(IBEO LUX, SICK LD-MRS), alone and beside paper N's HDL-64 in one bag.

The clouds are paper T's analytic LUX scans of a track between earth banks (``detector.traversable
.synthetic``), written as a driver would publish them: float32 points in the ROS frame, with the
layer index or without it, in firing order (angle by angle, the four layers interleaved).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.detector.loaders import sensor_to_ros_frame
from negobs_gym.detector.synthetic import HDL64_ELEVATION_DEG, Hole, synthetic_scan
from negobs_gym.detector.traversable import Box, TrackScene, TraversableConfig, TraversableRegionDetector
from negobs_gym.detector.traversable import synthetic_scan as lux_scan
from negobs_gym.detector.traversable.synthetic import LuxRig
from negobs_gym.sensors.rigs import LUX_FORWARD_M, paper_n_rig
from tests.helpers import pointcloud2, ros_ring_cloud

# paper T's LUX at the env rig's mount (on the front bumper, 0.65 m high, pitched 5.03 deg)
RIG = LuxRig(forward_m=LUX_FORWARD_M)
SCENE = TrackScene(
    left_half_width_m=3.5,
    right_half_width_m=4.5,
    boxes=(Box(x_m=0.5, y_m=9.0, size_x_m=1.0, size_y_m=1.0, height_m=1.0),),
)
FRAMES = 3


def _scans():
    """Three noisy LUX scans of the track (one noise draw each)."""
    return [lux_scan(SCENE, RIG, range_noise_m=0.02, rng=np.random.default_rng(k)) for k in range(FRAMES)]


def _cloud(scan, *, layer: bool = True) -> np.ndarray:
    """The scan's returns in the ROS frame, float32, in firing order (column by column)."""
    p = np.transpose(scan.points_sensor, (1, 0, 2))  # (columns, layers, 3): angle-major
    ok = np.isfinite(p).all(axis=-1)
    layers = np.broadcast_to(np.arange(scan.shape[0])[None, :], ok.shape)[ok]
    p = p[ok]
    fields = [(n, "<f4") for n in "xyz"] + [("intensity", "<f4")] + ([("layer", "<u2")] if layer else [])
    cloud = np.zeros(len(p), dtype=fields)
    cloud["x"], cloud["y"], cloud["z"] = sensor_to_ros_frame(p).T
    if layer:
        cloud["layer"] = layers
    return cloud


def _expected():
    """The detector run on the scans themselves, frame by frame."""
    detector = TraversableRegionDetector()
    return [detector.update(scan, Pose()) for scan in _scans()]


def _records(out: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(out.glob("0*.json"))]


def _write_pcd(path: Path, cloud: np.ndarray) -> str:
    pypcd4 = pytest.importorskip("pypcd4")
    names = list(cloud.dtype.names)
    columns = [np.ascontiguousarray(cloud[n]) for n in names]
    pypcd4.PointCloud.from_points(columns, names, [c.dtype for c in columns]).save(path)
    return str(path)


def _write_pcds(folder: Path, *, layer: bool) -> list[str]:
    folder.mkdir()
    return [_write_pcd(folder / f"lux_{k}.pcd", _cloud(scan, layer=layer)) for k, scan in enumerate(_scans())]


@pytest.mark.parametrize("layer", [True, False], ids=["layer_field", "no_layer_field"])
def test_lux_clouds_give_the_detectors_region(tmp_path, layer):
    files = _write_pcds(tmp_path / "clouds", layer=layer)
    out = tmp_path / "out"
    assert main(["detect", *files, "--sensor", "lux", "--out", str(out)]) == 0
    records = _records(out)
    assert len(records) == FRAMES
    for record, region in zip(records, _expected(), strict=True):
        assert record["ring_source"] == ("ring_field" if layer else "elevation_table")
        assert record["scan_shape"] == [4, 441]  # 0.25 deg columns over the 110 deg field of view
        assert "n_frame_pairs" not in record  # no paper N input, no paper N result
        got = record["traversable"]
        for side in ("left", "right"):
            line = getattr(region, f"{side}_line")
            assert got[f"{side}_line"]["slope"] == pytest.approx(line.slope, abs=1e-4)
            assert got[f"{side}_line"]["offset_m"] == pytest.approx(line.offset_m, abs=1e-3)
        assert got["traversable_cells"] == np.argwhere(region.traversable).tolist()
        assert got["positive_cells"] == np.argwhere(region.positive_obstacles).tolist()
        assert got["n_obstacles"] == len(region.obstacles) == 1
        assert got["obstacles"][0]["centre_xy_m"] == pytest.approx([0.5, 8.5], abs=0.3)  # the box's face
    # the boundaries are the track's banks (x = -3.5 and +4.5 m at the foot)
    last = records[-1]["traversable"]
    assert -4.0 < last["left_line"]["offset_m"] < -3.4 and 4.4 < last["right_line"]["offset_m"] < 5.0
    summary = json.loads((out / "summary.json").read_text())
    assert [s["boundaries"] for s in summary] == [["left", "right"]] * FRAMES
    assert all(s["n_traversable_cells"] > 1000 for s in summary)
    assert len(list(out.glob("*.png"))) == FRAMES


def test_set_changes_paper_ts_settings_and_the_shared_grid(tmp_path):
    files = _write_pcds(tmp_path / "clouds", layer=True)[:1]
    settings = ["--set", "traversable.boundary_layers=[0, 1]", "--set", "negative.grid.ahead_m=20"]
    assert main(["detect", *files, "--sensor", "lux", *settings, "--out", str(tmp_path / "out")]) == 0
    (record,) = _records(tmp_path / "out")
    region = record["traversable"]
    assert region["grid"]["shape"] == [125, 100] and len(region["raw_left_m"]) == 2
    two_layers = TraversableConfig(boundary_layers=(0, 1))
    expected = TraversableRegionDetector(two_layers, grid=GridSpec(ahead_m=20.0)).update(_scans()[0], Pose())
    assert region["traversable_cells"] == np.argwhere(expected.traversable).tolist()


def test_png_every_draws_every_nth_frame_and_writes_every_json(tmp_path):
    files = _write_pcds(tmp_path / "clouds", layer=True)
    out = tmp_path / "out"
    assert main(["detect", *files, "--sensor", "lux", "--png-every", "2", "--out", str(out)]) == 0
    assert [p.stem[:5] for p in sorted(out.glob("0*.png"))] == ["00000", "00002"]
    assert len(list(out.glob("0*.json"))) == FRAMES


def test_a_lux_cloud_missing_a_layer_exits_naming_it(tmp_path, capsys):
    cloud = _cloud(_scans()[0])
    path = _write_pcd(tmp_path / "lux_0.pcd", cloud[cloud["layer"] != 3])  # the top layer saw nothing
    assert main(["detect", path, "--sensor", "lux", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "lux_0.pcd" in err and "4-layer" in err and "got 3" in err


def _hdl64_cloud(near_m: float) -> np.ndarray:
    mount = next(m for m in paper_n_rig().mounts if m.name == "hdl64")
    azimuth = np.linspace(-np.pi, np.pi, 4000, endpoint=False) + np.pi / 4000
    scan = synthetic_scan(
        "hdl64",
        np.radians(HDL64_ELEVATION_DEG),
        azimuth,
        mount.rotation_matrix,
        np.array(mount.translation_m),
        [Hole.ahead(near_m, 1.0, 1.0, 0.8)],
    )
    return ros_ring_cloud(scan)


def test_a_rig_bag_runs_paper_n_and_paper_t_in_one_update(tmp_path):
    """The top HDL-64 at 10 Hz leads; the LUX at 25 Hz joins each update with its nearest cloud.
    Each sensor scans its own synthetic scene (a pit on flat ground; the track) standing still, so
    paper N's and paper T's results must equal each run on its own topic alone; the structure
    channel reads every return, the LUX's banks and box too."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    bag = tmp_path / "rig"
    start, lux_scans = 10**9, _scans()
    messages = []
    with Writer(bag, version=9) as writer:
        top = writer.add_connection("/top", "sensor_msgs/msg/PointCloud2", typestore=store)
        lux = writer.add_connection("/lux", "sensor_msgs/msg/PointCloud2", typestore=store)
        for k in range(FRAMES):
            stamp = start + k * 10**8
            messages.append((stamp, top, pointcloud2(store, _hdl64_cloud(8.5), stamp, frame_id="top")))
        for j in range(8):  # 25 Hz from 8 ms after the top's first: clouds 0, 2 and 5 are nearest
            stamp = start + 8 * 10**6 + j * 4 * 10**7
            cloud = _cloud(lux_scans[j % FRAMES])
            messages.append((stamp, lux, pointcloud2(store, cloud, stamp, frame_id="lux")))
        for stamp, connection, msg in sorted(messages, key=lambda m: m[0]):
            writer.write(connection, stamp, store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))
    rig = tmp_path / "rig_out"
    assert main(["detect", str(bag), "--cloud", "/top:hdl64", "--cloud", "/lux:lux", "--out", str(rig)]) == 0
    alone = {}
    for topic, sensor in (("/top", "hdl64"), ("/lux", "lux")):
        alone[topic] = tmp_path / sensor
        args = [
            "detect",
            str(bag),
            "--topic",
            topic,
            "--sensor",
            sensor,
            "--no-png",
            "--out",
            str(alone[topic]),
        ]
        assert main(args) == 0
    records, top_alone, lux_alone = _records(rig), _records(alone["/top"]), _records(alone["/lux"])
    assert len(records) == FRAMES and len(lux_alone) == 8
    lux_frames = []
    for record, top_record in zip(records, top_alone, strict=True):
        assert record["fused_pairs"] == top_record["fused_pairs"]
        assert record["grid"] == top_record["grid"] and record["n_obstacles"] == top_record["n_obstacles"]
        (cloud,) = [c for c in record["clouds"] if c["topic"] == "/lux"]
        assert cloud["sensor"] == "lux" and cloud["input"] == "lux" and abs(cloud["dt_s"]) <= 0.02
        lux_frames.append(cloud["frame"])
        assert record["traversable"]["left_line"] is not None
    assert record["n_obstacles"] >= 1  # the pit, confirmed by the third frame
    assert lux_frames == [0, 2, 5]
    # paper T saw clouds 0, 2, 5 in the rig, every cloud alone: its Kalman filters differ, the
    # boundaries of the first update (cloud 0 in both) do not
    assert records[0]["traversable"] == lux_alone[0]["traversable"]


def test_a_real_mrs1104_capture_keeps_every_return(tmp_path):
    """SICK's MRS1104 (4 layers at -2.5, 0, 2.5 and 5 deg, 0.25 deg steps over 275 deg) recorded
    indoors (tests/data/real): its returns lie at multiples of 0.25 deg, where the spinning
    sensors' column edges would lose a quarter of them to shared columns; the LUX's centred
    columns keep each, by its ring field or, without one, by its layer-by-layer point order."""
    from negobs_gym.detector.io import ScanSetup
    from negobs_gym.detector.io.pcd import read_pcd
    from tests import mrs1104

    frames = mrs1104.clouds(FRAMES)
    files = [_write_pcd(tmp_path / f"mrs1104_{k}.pcd", cloud) for k, cloud in enumerate(frames)]
    table = tuple(np.radians([-2.5, 0.0, 2.5, 5.0]))  # bounds the rings of a cloud read by point order
    setup = ScanSetup(sensor="lux", azimuth_resolution_deg=0.25, elevation_rad=table, columns_centred=True)
    for path, cloud in zip(files, frames, strict=True):
        frame = read_pcd(path, setup)
        assert frame.ring_source == "ring_field" and int(frame.scan.valid.sum()) == len(cloud) > 4300
        np.testing.assert_allclose(np.degrees(frame.scan.elevation_rad), [-2.5, 0.0, 2.5, 5.0], atol=1e-6)
        columns = np.flatnonzero(frame.scan.valid.any(axis=0))
        np.testing.assert_allclose(np.degrees(frame.scan.azimuth_rad[columns[[0, -1]]]), [-137.5, 137.5])
        edges = read_pcd(path, ScanSetup(sensor="lux", azimuth_resolution_deg=0.25))
        assert int(edges.scan.valid.sum()) < 0.8 * len(cloud)
        bare = _write_pcd(tmp_path / "bare.pcd", cloud[["x", "y", "z"]])
        by_order = read_pcd(bare, setup)
        assert by_order.ring_source == "point_order"
        np.testing.assert_array_equal(by_order.scan.ranges_m, frame.scan.ranges_m)
    out = tmp_path / "out"
    assert main(["detect", *files, "--sensor", "lux", "--out", str(out)]) == 0
    # merged by angle and without its ring field, the MRS1000 table assigns the same layers
    merged = frames[0][np.argsort(np.arctan2(frames[0]["y"], frames[0]["x"]), kind="stable")]
    table_out = tmp_path / "table"
    merged_file = _write_pcd(tmp_path / "merged.pcd", merged[["x", "y", "z"]])
    assert main(["detect", merged_file, "--sensor", "mrs1000", "--out", str(table_out)]) == 0
    (by_table,) = _records(table_out)
    assert by_table["ring_source"] == "elevation_table"
    by_field = _records(out)[0]["traversable"]
    # the same ranges; the rows at the table's elevations instead of the measured ones (1e-8 deg
    # apart) move 4 of the obstacle's 1,502 returns across a threshold on these mm-quantised ranges
    by_table = by_table["traversable"]
    (table_cluster,), (field_cluster,) = by_table.pop("obstacles"), by_field.pop("obstacles")
    assert by_table == by_field
    assert table_cluster["n_points"] == pytest.approx(field_cluster["n_points"], rel=0.01)
    for record in _records(out):
        assert record["scan_shape"] == [4, 1101] and record["n_points"] > 4300  # 1,101 beams, 275 deg
        # a room: no ground within the layers' reach, so no road between two boundaries
        region = record["traversable"]
        assert region["traversable_cells"] == [] and region["right_line"] is None
