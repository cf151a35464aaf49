"""Detection campaign: Table 6/7 counts add up, JSON round-trips, PNGs, workers/Ray/resume give equal CSVs."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.errors import ConfigError
from negobs_gym.eval import DetectionEvalConfig
from negobs_gym.eval.campaign import read_csv
from negobs_gym.eval.detection_campaign import (
    FRAME_COLUMNS,
    OBSTACLE_COLUMNS,
    DetectionCampaignConfig,
    DetectionSummary,
    episodes,
    report_markdown,
    summarize,
)
from negobs_gym.eval.tables import PAPER_N_TABLE6, PAPER_N_TABLE7, paper_n_fig16_fused

PNG = b"\x89PNG\r\n\x1a\n"
REPO = Path(__file__).resolve().parents[2]
QUICK = ["--rig", "reduced", "--no-progress"]  # half-resolution rig: the default suite stays fast


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("detection")
    assert main(["-q", "eval", "detection", "--seeds", "2", "--frames", "60", "--out", str(out), *QUICK]) == 0
    return out


def test_tables_add_up_and_match_the_rows(campaign: Path) -> None:
    summary = DetectionSummary.from_json((campaign / "summary.json").read_text())
    rows = read_csv(campaign / "obstacles.csv")
    frames = read_csv(campaign / "frames.csv")
    assert summary.frames == len(frames) == 60 and summary.episodes == 2
    assert summary.km == pytest.approx(sum(float(r["travelled_m"]) for r in frames) / 1000)
    occ = np.asarray(summary.occurrences)
    assert occ.shape == (7, 7) and occ.sum() > 0
    cfg = DetectionEvalConfig()
    cells = np.array([int(r["cells"]) for r in rows])
    dist = np.array([float(r["centre_distance_m"]) for r in rows])
    in_bins = (cells >= 15) & (cells < 56) & (dist >= 6) & (dist < 20)
    assert occ.sum() == in_bins.sum()
    for mode in ("fused", "hdl64", "hdl32"):
        recalled = np.asarray(summary.recalled[mode])
        hit = np.array([r[f"recalled_{mode}"] == "1" for r in rows])
        missed = np.zeros_like(occ)
        s = np.digitize(cells, cfg.size_bin_edges_cells) - 1
        d = np.digitize(dist, cfg.distance_bin_edges_m) - 1
        np.add.at(missed, (s[in_bins & ~hit], d[in_bins & ~hit]), 1)
        np.testing.assert_array_equal(recalled + missed, occ)  # recalled + missed = occurrences
        assert (
            sum(summary.false_alarms[mode][k] for k in ("on_track", "off_track"))
            == (summary.false_alarms[mode]["total"])
        )
    # the detector finds near pits: the 6-10 m recall of the fused rig is well above zero
    near = np.asarray(summary.recalled["fused"])[:, :2].sum() / max(occ[:, :2].sum(), 1)
    assert near > 0.5


def test_summary_json_round_trips_and_files_are_written(campaign: Path) -> None:
    text = (campaign / "summary.json").read_text()
    summary = DetectionSummary.from_json(text)
    assert summary.to_json() == text
    assert DetectionSummary.from_json(summary.to_json()) == summary
    assert (campaign / "obstacles.csv").read_text().splitlines()[0] == ",".join(OBSTACLE_COLUMNS)
    assert (campaign / "frames.csv").read_text().splitlines()[0] == ",".join(FRAME_COLUMNS)
    for png in ("fig16.png", "recall_heatmap.png"):
        assert (campaign / png).read_bytes()[:8] == PNG
    tables = (campaign / "tables.md").read_text()
    assert "(0.977)" in tables and "(86)" in tables  # paper N's values beside ours
    assert not list(campaign.rglob("*.tmp"))


def test_summarize_bins_hand_made_rows(tmp_path: Path) -> None:
    obstacles = tmp_path / "o.csv"
    frames = tmp_path / "f.csv"
    rows = [
        "a,0,0,pit-0,25,6.5,1,1,0",  # 25-29 x 6-8: hit (fused, hdl64)
        "a,0,1,pit-0,25,7.9,0,0,1",  # same bin: missed by fused
        "a,0,1,pit-1,14,7.0,1,1,1",  # 14 cells: below every size bin
        "a,0,1,pit-2,40,21.0,0,0,0",  # beyond 20 m
        "a,0,1,pit-3,55,19.9,1,0,0",  # 45-55 x 18-20
    ]
    obstacles.write_text(",".join(OBSTACLE_COLUMNS) + "\n" + "\n".join(rows) + "\n")
    fa = ["1,0,2", "0,0,0", "3,1,0"]  # per mode: detections, false alarms on, off
    frame_rows = [f"a,0,{k},5.0,0.5,0.0,{fa[0]},{fa[1]},{fa[2]}" for k in range(2)]
    frames.write_text(",".join(FRAME_COLUMNS) + "\n" + "\n".join(frame_rows) + "\n")
    s = summarize(obstacles, frames, DetectionEvalConfig())
    occ = np.asarray(s.occurrences)
    assert occ.sum() == 3 and occ[2, 0] == 2 and occ[6, 6] == 1
    assert np.asarray(s.recalled["fused"])[2, 0] == 1 and np.asarray(s.recalled["hdl32"])[2, 0] == 1
    assert s.recall("fused")[2, 0] == 0.5 and np.isnan(s.recall("fused")[0, 0])
    assert s.fig16["fused"][0] == 0.5 and s.fig16["fused"][1] is None
    assert s.false_alarms["fused"] == {"total": 4, "on_track": 0, "off_track": 4}
    assert s.false_alarms["hdl32"] == {"total": 2, "on_track": 2, "off_track": 0}
    rates = s.false_alarm_rates("fused")
    assert rates["per_frame"] == 2.0 and rates["total_per_km"] == pytest.approx(4000.0)
    assert s.fig16_interval["fused"] == [None] * 7  # one course: nothing to resample


def test_fig16_intervals_resample_the_courses(tmp_path: Path) -> None:
    # four courses see a 25-cell pit at 6-8 m on 10 frames each: two recall it every frame, two never
    obstacles, frames = tmp_path / "o.csv", tmp_path / "f.csv"
    rows = [f"c{c},{c},{k},pit-0,25,7.0,{int(c < 2)},1,0" for c in range(4) for k in range(10)]
    obstacles.write_text(",".join(OBSTACLE_COLUMNS) + "\n" + "\n".join(rows) + "\n")
    frames.write_text(",".join(FRAME_COLUMNS) + "\n" + f"c0,0,0,5.0,0.5,0.0,{'0,0,0,' * 2}0,0,0\n")
    s = summarize(obstacles, frames, DetectionEvalConfig())
    assert s.fig16["fused"][0] == 0.5
    low, high = s.fig16_interval["fused"][0]
    # the frames of a course are not independent: the interval spans the courses' spread (every
    # resample of four courses lies in 0..1), far wider than 20 of 40 frames as binomial draws
    assert low <= 0.25 and high >= 0.75
    assert s.fig16_interval["hdl64"][0] == [1.0, 1.0]  # every course, every frame
    assert s.fig16_interval["fused"][1] is None  # nothing seen at 8-10 m
    assert "0.500 (" in report_markdown(s)


def test_paper_reference_values() -> None:
    assert np.asarray(PAPER_N_TABLE6).shape == np.asarray(PAPER_N_TABLE7).shape == (7, 7)
    # Table 6 holds every one of the 5350 obstacles marked in paper N §4.1
    assert np.asarray(PAPER_N_TABLE6).sum() == 5350
    # Fig. 16 fused reference at 6-8 m: Table 7's 25-29 and 30-34 rows weighted by Table 6
    assert paper_n_fig16_fused()[0] == pytest.approx((101 * 0.96 + 85 * 0.941) / 186, abs=1e-3)


def test_config_validation_and_frame_split() -> None:
    cfg = DetectionCampaignConfig(seeds=3, frames=10)
    assert [e.args["frames"] for e in episodes(cfg)] == [4, 3, 3]
    for kwargs, field in (
        ({"seeds": 0}, "seeds"),
        ({"seeds": 5, "frames": 4}, "frames"),
        ({"rig": "huge"}, "rig"),
        ({"min_speed_mps": 9.0}, "min_speed_mps"),
        ({"spacing_m": (3.0, 1.0)}, "spacing_m"),
    ):
        with pytest.raises(ConfigError, match=field):
            DetectionCampaignConfig(**kwargs)


def _small(out: Path, *extra: str) -> list[str]:
    return ["-q", "eval", "detection", "--seeds", "2", "--frames", "6", "--out", str(out), *QUICK, *extra]


@pytest.mark.slow
def test_ray_gives_byte_identical_csvs(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    assert main(_small(tmp_path / "serial")) == 0
    assert main(_small(tmp_path / "ray", "--ray")) == 0
    for name in ("obstacles.csv", "frames.csv", "summary.json"):
        assert (tmp_path / "serial" / name).read_bytes() == (tmp_path / "ray" / name).read_bytes()


# finished parts only, not the hidden temp file a part is written through (".seed00000.json.*.tmp.json")
FINISHED_PART = "seed*.json"


def test_killed_campaign_resumes_to_the_same_csv_two_workers_write(tmp_path: Path) -> None:
    """A campaign killed after its first part and resumed in one process writes, byte for byte,
    the files the whole campaign writes in two worker processes."""
    args = ["eval", "detection", "--seeds", "4", "--frames", "12", *QUICK]
    killed = tmp_path / "killed"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen(
        [sys.executable, "-m", "negobs_gym.cli", "-q", *args, "--out", str(killed)],
        cwd=REPO,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    parts = killed / "parts"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and len(list(parts.glob(FINISHED_PART))) < 1 and proc.poll() is None:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    finished = sorted(p.name for p in parts.glob(FINISHED_PART))
    assert 1 <= len(finished) < 4, f"kill came too late or too early: {finished}"
    assert not (killed / "obstacles.csv").exists()
    stamps = {p.name: p.stat().st_mtime_ns for p in parts.glob(FINISHED_PART)}
    assert main(["-q", *args, "--out", str(killed), "--resume"]) == 0
    assert {n: (parts / n).stat().st_mtime_ns for n in finished} == stamps  # finished ones not rerun
    assert main(["-q", *args, "--workers", "2", "--out", str(tmp_path / "whole")]) == 0
    for name in ("obstacles.csv", "frames.csv", "summary.json"):
        assert (killed / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name


def test_course_counts_on_other_seeds_fill_courses_without_rows(tmp_path: Path) -> None:
    from negobs_gym.eval.detection_campaign import fig16_counts_by_course

    obstacles = tmp_path / "o.csv"
    rows = ["c3,3,0,pit-0,25,7.0,1,0,0", "c3,3,1,pit-0,25,9.0,0,0,0", "c5,5,0,pit-0,30,7.5,1,1,0"]
    obstacles.write_text(",".join(OBSTACLE_COLUMNS) + "\n" + "\n".join(rows) + "\n")
    counts = fig16_counts_by_course(obstacles, DetectionEvalConfig())
    assert counts.seeds.tolist() == [3, 5] and counts.seen[:, :2].tolist() == [[1, 1], [1, 0]]
    # seed 4 drove past no pit of Fig. 16's sizes (no row), seed 9 lies beyond every seed here
    on = counts.on([5, 4, 3, 9])
    assert on.seeds.tolist() == [5, 4, 3, 9]
    assert on.seen[:, :2].tolist() == [[1, 0], [0, 0], [1, 1], [0, 0]]
    assert on.recalled["fused"][:, 0].tolist() == [1, 0, 1, 0] and on.recalled["hdl64"][:, 0].tolist() == [
        1,
        0,
        0,
        0,
    ]
    assert on.recall("fused")[:2].tolist() == [1.0, 0.0]
