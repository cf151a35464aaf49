"""``negobs detect --truth``: paper N's recall on a recorded drive whose negative obstacles were
surveyed, on the synthetic rig bag of ``test_detect_rig`` (a 1 x 1 m pit approached at 25 km/h,
8.5 m ahead of the vehicle at the first cloud; the odometry frame's x is the drive's direction)."""

from __future__ import annotations

import json

import pytest

from negobs_gym.cli import main
from tests.cli.test_detect_rig import CLOUDS, FRAMES, NEAR_M, rig_bag  # noqa: F401 (a fixture)

# the pit in the odometry frame (ROS axes): 8.5-9.5 m along x, +-0.5 m across
PIT = [[NEAR_M, -0.5], [NEAR_M + 1.0, -0.5], [NEAR_M + 1.0, 0.5], [NEAR_M, 0.5]]
# surveyed, but not there: 12 m along, 3 m to the left
NOT_THERE = [[12.0, 2.5], [13.0, 2.5], [13.0, 3.5], [12.0, 3.5]]


@pytest.fixture
def survey(tmp_path):
    path = tmp_path / "survey.json"
    obstacles = [{"name": "pit", "outline_xy_m": PIT}, {"name": "not there", "outline_xy_m": NOT_THERE}]
    path.write_text(json.dumps({"negative_obstacles": obstacles}))
    return path


def _run(bag, out, *extra) -> tuple[list[dict], dict]:
    args = ["-q", "detect", str(bag), "--no-png", "--poses-topic", "/odom", "--out", str(out)]
    assert main([*args, *extra]) == 0
    records = [json.loads((out / f"{k:05d}_rig_{k:04d}.json").read_text()) for k in range(FRAMES)]
    return records, json.loads((out / "recall.json").read_text())


def test_the_rig_recalls_the_surveyed_pit_in_every_update(rig_bag, survey, tmp_path):  # noqa: F811
    records, recall = _run(rig_bag, tmp_path / "rig", *CLOUDS, "--truth", str(survey))
    for k, record in enumerate(records):
        pit, not_there = record["truth"]["obstacles"]
        assert pit["name"] == "pit" and pit["recalled"] and pit["cells"] == 25  # 5 x 5 cells of 20 cm
        # paper N §4.2 bins by the marked region's centre: the vehicle drives 0.7 m per update
        assert pit["centre_distance_m"] == pytest.approx(NEAR_M + 0.5 - 0.7 * k, abs=0.15)
        assert not_there["name"] == "not there" and not not_there["recalled"]
        assert record["truth"]["false_alarms"] == 0
    assert recall["frames"] == FRAMES
    # the pit at 6-8 and 8-10 m, the surveyed obstacle that is not there at 10-12 and 12-14 m
    assert recall["seen_by_distance"] == [2, 2, 2, 2, 0, 0, 0]
    assert recall["recalled_by_distance"] == [2, 2, 0, 0, 0, 0, 0]
    assert recall["per_obstacle"]["pit"] == {"frames": 4, "recalled": 4}
    assert recall["per_obstacle"]["not there"] == {"frames": 4, "recalled": 0}
    assert recall["seen"][2][:2] == [2, 2]  # Table 7: 25-29 cells
    text = (tmp_path / "rig" / "recall.md").read_text()
    assert "| 6-8 m | 2 | 2 | 1.000 |" in text and "False alarms: 0 (0.000 per frame)" in text
    # the top HDL-64 alone confirms the pit from the third frame (paper N §4.2): 8-10 m unrecalled
    top, top_recall = _run(rig_bag, tmp_path / "top", "--topic", "/top", "--truth", str(survey))
    assert [r["truth"]["obstacles"][0]["recalled"] for r in top] == [False, False, True, True]
    assert top_recall["recall_by_distance"][:4] == [1.0, 0.0, 0.0, 0.0]
