"""``negobs detect`` end to end on the committed real HDL-32E capture, and on bad files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.core.pose import Pose
from negobs_gym.detector import NegativeObstacleDetector, StructureDetector
from negobs_gym.detector.io import ScanSetup, read_recording

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
HDL32E_B = REAL / "hdl32e_b.pcap"
# paper N's pairs, without the default's ground checks: the street capture's range gaps (22 of
# them), which the deskew and mounting tests move; the checks leave 3 (docs/detector_false_alarms.md)
PAPER_PAIRS = [
    arg
    for check in ("crest_rise_m=inf", "far_rise_m=inf", "min_depth_ratio=0.0")
    for arg in ("--set", f"negative.hdl64_ground_checks.{check}")
]
pytest.importorskip("velodyne_decoder")


def test_detect_writes_png_and_json_that_round_trip(tmp_path):
    out = tmp_path / "out"
    args = ["-q", "detect", str(HDL32E_B), str(HDL32E_B), str(HDL32E_B), "--sensor", "hdl32"]
    assert main([*args, "--height", "2.3", "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    stems = [f"{n:05d}_hdl32e_b_0000" for n in range(3)]
    files = [*(s + ".json" for s in stems), *(s + ".png" for s in stems), "summary.json", "config.json"]
    assert names == sorted(files)
    assert all((out / f"{s}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for s in stems)
    # the same three frames through the API (standing still: identity pose every frame)
    setup = ScanSetup(azimuth_resolution_deg=0.16, elevation_rad=(), translation_m=(0.0, 0.0, 2.3))
    detector = NegativeObstacleDetector()
    for stem in stems:
        frame = next(read_recording(HDL32E_B, setup))
        det = detector.update({"hdl64": frame.scan}, Pose())
        record = json.loads((out / f"{stem}.json").read_text())
        assert record["ring_source"] == "ring_field" and record["n_points"] == 30596
        assert record["height_m"] == 2.3 and record["scan_shape"] == [32, 2250]
        assert record["n_frame_pairs"] == len(det.frame_pairs["hdl64"]) > 0
        np.testing.assert_allclose(
            record["frame_pairs"]["hdl64"]["a_m"], det.frame_pairs["hdl64"].a_m, atol=1e-4
        )
        assert record["fused_pairs"]["confirmed"] == det.pairs.confirmed.tolist()
        assert record["n_obstacles"] == len(record["obstacles"]) == len(det.obstacles)
        for ob_json, ob in zip(record["obstacles"], det.obstacles, strict=True):
            np.testing.assert_allclose(ob_json["outline_xy_m"], ob.outline_xy_m, atol=1e-4)
        grid = np.zeros(record["grid"]["shape"], dtype=bool)
        grid[tuple(np.array(record["grid"]["occupied_cells"], dtype=int).reshape(-1, 2).T)] = True
        np.testing.assert_array_equal(grid, det.grid)
        structure = np.zeros(record["grid"]["shape"], dtype=bool)
        structure[tuple(np.array(record["structure_cells"], dtype=int).reshape(-1, 2).T)] = True
        want = StructureDetector(grid=detector.config.grid).update({"hdl64": frame.scan}, Pose())
        np.testing.assert_array_equal(structure, want)
        assert 0 < structure.sum() < structure.size // 4  # walls and cars, not the whole ground
    summary = json.loads((out / "summary.json").read_text())
    assert [s["frame"] for s in summary] == stems
    assert all(s["n_structure_cells"] > 0 for s in summary)


@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("cut.bin", np.zeros(7, np.float32).tobytes(), "not a multiple of 4"),
        ("empty.pcap", b"", "file is empty"),
        ("junk.pcd", b"# .PCD v0.7\nFIELDS x y\n", "not a readable PCD"),
    ],
)
def test_bad_file_exits_non_zero_with_one_line(tmp_path, capsys, name, content, match):
    bad = tmp_path / name
    bad.write_bytes(content)
    assert main(["detect", str(bad), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("negobs detect: ") and match in err
    assert "Traceback" not in err


def test_help_says_frames_stand_still(capsys):
    with pytest.raises(SystemExit):
        main(["detect", "--help"])
    assert "standing still" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("sensor", ["hdl64", "hdl32", "hdl32-left", "hdl32-right", "vlp16", "vlp32c"])
def test_sensor_choices_give_paper_n_mounts(sensor):
    from negobs_gym.cli import build_parser
    from negobs_gym.cli.detect_sensors import scan_setup
    from negobs_gym.sensors.rigs import paper_n_rig

    setup = scan_setup(build_parser().parse_args(["detect", "f.bin", "--out", "o", "--sensor", sensor]))
    mount = {m.name: m for m in paper_n_rig().mounts}[setup.sensor]
    assert setup.sensor == ("hdl64" if "-" not in sensor else sensor.replace("-", "_"))
    np.testing.assert_array_equal(setup.rotation, mount.rotation_matrix)
    assert setup.translation_m == mount.translation_m  # default height: the rig's
    assert (len(setup.elevation_rad) == 0) == (sensor == "vlp32c")
    high = scan_setup(
        build_parser().parse_args(["detect", "f.bin", "--out", "o", "--sensor", sensor, "--height", "1.5"])
    )
    assert high.translation_m[2] == 1.5


def test_pcap_sequence_json_only(tmp_path):
    out = tmp_path / "out"
    args = ["-q", "detect", str(REAL / "hdl32e_a.pcap"), "--sensor", "hdl32", "--height", "3.1"]
    assert main([*args, "--no-png", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "00000_hdl32e_a_0000.json",
        "00001_hdl32e_a_0001.json",
        "config.json",
        "summary.json",
    ]
    summary = json.loads((out / "summary.json").read_text())
    assert [s["n_points"] for s in summary] == [18154, 1425]


def test_png_height_image_keeps_the_highest_return_per_pixel():
    from negobs_gym.cli.detect_report import _highest_return

    pts = np.array(
        [[0.01, 0.01, 0.2], [0.02, 0.03, 1.1], [0.03, 0.02, -0.4], [0.12, 0.01, 0.5], [0.99, 1.99, 0.7]]
    )
    image = _highest_return(pts, (0.0, 1.0, 0.0, 2.0), 0.05)
    assert image.shape == (40, 20)
    assert image[0, 0] == 1.1  # three returns in the first pixel: the highest drawn
    assert image[0, 2] == 0.5 and image[39, 19] == 0.7  # the last pixel holds the far corner
    assert int(image.count()) == 3  # every other pixel masked: no return there


def test_a_real_capture_deskewed_by_an_ins_log(tmp_path):
    """hdl32e_b's revolution fired over the 50 ms before its capture time: standing still, deskewing
    changes nothing; driving at 7 m/s along the log's x, each pair moves back by the vehicle's
    travel between its column's firing and the capture time."""
    host = 1355262378.019387  # the revolution's capture time (the decoder's host stamp)
    args = ["-q", "detect", str(HDL32E_B), "--sensor", "hdl32", "--height", "2.3", "--no-png", *PAPER_PAIRS]
    runs = {}
    for name, speed, extra in (
        ("raw", 7.0, ()),
        ("still", 0.0, ("--deskew",)),
        ("moving", 7.0, ("--deskew",)),
    ):
        log = tmp_path / f"{name}.csv"
        rows = [f"{t:.6f},{speed * (t - host):.6f},0,0,0,0,0" for t in (host - 0.5, host + 0.5)]
        log.write_text("timestamp,x,y,z,roll,pitch,yaw\n" + "\n".join(rows) + "\n")
        assert main([*args, "--out", str(tmp_path / name), "--poses-track", str(log), *extra]) == 0
        runs[name] = json.loads((tmp_path / name / "00000_hdl32e_b_0000.json").read_text())
    raw, still, moving = (
        np.array(runs[k]["frame_pairs"]["hdl64"]["a_m"]) for k in ("raw", "still", "moving")
    )
    assert len(raw) > 10
    np.testing.assert_allclose(still, raw, atol=1e-9)
    # moving along Y leaves a pair's x and z: match each deskewed A to its raw one by them (the
    # moved ground map keeps 20 of the 22)
    gap = np.abs(moving[:, None, 0] - raw[None, :, 0]) + np.abs(moving[:, None, 2] - raw[None, :, 2])
    assert len(moving) >= len(raw) - 3 and np.all(gap.min(axis=1) < 1e-6)
    shift = moving[:, 1] - raw[gap.argmin(axis=1), 1]  # fired up to 50 ms early: seen from behind
    assert np.all((shift > -7.0 * 0.05 - 1e-3) & (shift < 1e-3)) and shift.min() < -0.05
    assert runs["moving"]["deskewed"] and not runs["raw"]["deskewed"]


def test_set_changes_one_detector_setting_and_config_json_records_it(tmp_path, capsys):
    args = ["detect", str(HDL32E_B), "--sensor", "hdl32", "--height", "2.3", "--no-png"]
    assert main([*args, "--out", str(tmp_path / "flag"), "--tighten-pairs"]) == 0
    set_by_path = [*args, "--out", str(tmp_path / "set"), "--set", "negative.fusion.tighten_on_match=true"]
    assert main([*set_by_path, "--set", "negative.grid.ahead_m=20", "--set", "structure.max_height_m=2"]) == 0
    flag, by_path = (json.loads(next((tmp_path / d).glob("00000_*")).read_text()) for d in ("flag", "set"))
    assert by_path["frame_pairs"] == flag["frame_pairs"]
    assert by_path["grid"]["shape"] == [125, 100] and flag["grid"]["shape"] == [175, 100]  # 20 + 5 m by 20 m
    config = json.loads((tmp_path / "set" / "config.json").read_text())
    negative = config["negative"]
    assert negative["fusion"]["tighten_on_match"] is True and negative["grid"]["ahead_m"] == 20
    assert config["structure"]["max_height_m"] == 2.0 and config["traversable"]["vehicle_width_m"] == 2.0
    assert config["set"][0] == "negative.fusion.tighten_on_match=true"
    for bad, message in (
        ("negative.fusion.priorx=0.4", "negative.fusion.priorx: no such setting; negative.fusion has"),
        ("paper_n.fusion.prior=0.4", "starts with the detector, one of negative, traversable, structure"),
        ("negative.fusion.prior=2", "negative.fusion.prior=2: prior: must be in (0, 1)"),
    ):
        assert main([*args, "--out", str(tmp_path / "bad"), "--set", bad]) == 2
        assert message in capsys.readouterr().err


@pytest.mark.parametrize("sensor", ["hdl64", "hdl32-left", "hdl32-right", "lux"])
def test_mount_in_ros_axes_gives_the_rig_mounting(sensor):
    """Each rig mount written as --mount (ROS body axes, degrees) is that mount again."""
    from scipy.spatial.transform import Rotation

    from negobs_gym.cli import build_parser
    from negobs_gym.cli.detect_sensors import scan_setup
    from negobs_gym.detector.io.setup import PACKAGE_TO_ROS_BODY

    rig = scan_setup(build_parser().parse_args(["detect", "f", "--out", "o", "--sensor", sensor]))
    ros = PACKAGE_TO_ROS_BODY @ np.asarray(rig.rotation) @ PACKAGE_TO_ROS_BODY.T
    x, y, z = PACKAGE_TO_ROS_BODY @ np.asarray(rig.translation_m)
    mount = ",".join(str(v) for v in (x, y, z, *Rotation.from_matrix(ros).as_euler("xyz", degrees=True)))
    args = build_parser().parse_args(["detect", "f", "--out", "o", "--sensor", sensor, "--mount", mount])
    setup = scan_setup(args)
    np.testing.assert_allclose(setup.rotation, rig.rotation, atol=1e-12)
    np.testing.assert_allclose(setup.translation_m, rig.translation_m, atol=1e-12)


def test_mount_moves_the_pairs_with_the_sensor(tmp_path, capsys):
    args = ["-q", "detect", str(HDL32E_B), "--sensor", "hdl32", "--no-png", *PAPER_PAIRS]
    assert main([*args, "--height", "2.3", "--out", str(tmp_path / "height")]) == 0
    # the same sensor 1.5 m ahead of the rear axle
    assert main([*args, "--mount", "1.5,0,2.3,0,0,0", "--out", str(tmp_path / "mount")]) == 0
    (by_height,), (by_mount,) = (
        [json.loads(p.read_text()) for p in (tmp_path / d).glob("00000_*.json")] for d in ("height", "mount")
    )
    np.testing.assert_allclose(by_mount["mounting"]["translation_m"], [0.0, 1.5, 2.3], atol=1e-12)
    a_height = np.array(by_height["frame_pairs"]["hdl64"]["a_m"])
    a_mount = np.array(by_mount["frame_pairs"]["hdl64"]["a_m"])
    # the pairs are the same pairs 1.5 m farther ahead, but for a few at the edges of the
    # detector's range and ROI, which are measured from the vehicle origin
    shifted = a_height + np.array([0.0, 1.5, 0.0])
    same = np.linalg.norm(a_mount[:, None] - shifted[None], axis=-1).min(axis=1) < 1e-3
    assert same.sum() > 0.7 * len(a_height) and same.mean() > 0.9
    for clash in (["--height", "2.0"], ["--cloud", "/a:hdl64"]):
        assert main([*args, "--mount", "0,0,2,0,0,0", *clash, "--out", str(tmp_path / "x")]) == 2
        assert "--mount sets the whole mounting" in capsys.readouterr().err
    # turned about its spin axis it stays on its path; rolled it does not, and is told so
    assert main([*args, "--mount", "0,0,2.3,0,0,90", "--out", str(tmp_path / "turned")]) == 0
    assert "spin axis" not in capsys.readouterr().err
    assert main([*args, "--mount", "0,0,2.3,90,0,0", "--out", str(tmp_path / "rolled")]) == 0
    assert "tilts the sensor's spin axis 90.0 deg from the --sensor hdl32" in capsys.readouterr().err
