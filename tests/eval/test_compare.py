"""Comparing campaigns: pairing by seed, choosing groups, the tests' figures, the files written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from negobs_gym.cli import main
from negobs_gym.errors import ConfigError
from negobs_gym.eval.braking_campaign import COLUMNS as BRAKING_COLUMNS
from negobs_gym.eval.campaign import format_row
from negobs_gym.eval.compare import (
    compare_campaigns,
    compare_detection_campaigns,
    load_side,
    load_sides,
    split_side,
    write_comparison,
)
from negobs_gym.eval.detection_campaign import FRAME_COLUMNS, OBSTACLE_COLUMNS
from negobs_gym.eval.policy_campaign import COLUMNS as POLICY_COLUMNS


def write_table(path: Path, columns: tuple[str, ...], rows: list[dict[str, object]]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    full = [dict.fromkeys(columns, 0) | row for row in rows]  # unnamed columns 0
    lines = [format_row(r[c] for c in columns) for r in full]
    path.write_text(",".join(columns) + "\n" + "\n".join(lines) + "\n")
    return path.parent


def policy_campaign(folder: Path, groups: dict[str, list[tuple[int, int, float]]]) -> Path:
    """A policy.csv: per filter setting, (seed, goal, progress_m) of each episode."""
    rows = [
        {"episode": f"{flt}.{seed}", "env": "negobs_gym/OffroadTrack-v0", "filter": flt, "seed": seed}
        | {"goal": goal, "success": goal, "progress_m": progress, "distance_m": progress}
        for flt, episodes in groups.items()
        for seed, goal, progress in episodes
    ]
    return write_table(folder / "policy.csv", POLICY_COLUMNS, rows)


def test_two_groups_of_one_campaign_pair_by_seed(tmp_path: Path) -> None:
    # seed 5 only without the filter: left out; of the rest, 3 goals only without, 1 only with
    off = [(0, 1, 100.0), (1, 1, 90.0), (2, 1, 80.0), (3, 0, 20.0), (4, 1, 95.0), (5, 1, 99.0)]
    on = [(4, 1, 90.0), (3, 1, 100.0), (2, 0, 60.0), (1, 0, 50.0), (0, 0, 40.0)]
    folder = policy_campaign(tmp_path / "run", {"nofilter": off, "filter": on})
    c = compare_campaigns(*load_sides(str(folder)))
    assert (c.a.group, c.b.group, c.pairs, c.only_a, c.only_b) == ("nofilter", "filter", 5, 1, 0)
    goal = next(r for r in c.rates if r.name == "goal")
    assert (goal.a, goal.b, goal.a_only, goal.b_only) == (4, 2, 3, 1)
    assert goal.p_value == pytest.approx(0.625)  # 2 * P(X <= 1), X ~ Bin(4, 1/2)
    progress = next(s for s in c.shifts if s.name == "progress_m")
    # differences by seed: 60, 40, 20, -80, 5 -> median 20
    assert progress.pairs == 5 and progress.median_difference == pytest.approx(20.0)
    # naming A's group first turns the sides round
    flipped = compare_campaigns(*load_sides(f"{folder}:filter"))
    assert (flipped.a.group, flipped.b.group) == ("filter", "nofilter")
    assert next(r for r in flipped.rates if r.name == "goal").difference == -goal.difference
    text = c.markdown()
    assert "5 episodes paired by seed; left out, their seed on one side only: 1 of A, 0 of B" in text
    assert "| goal | 5 | 4 (0.38-0.96) | 2 (0.12-0.77) | 3 | 1 | +0.40 | 0.625 |" in text


def test_two_campaigns_and_the_files_written(tmp_path: Path, capsys) -> None:
    a = policy_campaign(tmp_path / "a", {"filter": [(s, 1, 100.0) for s in range(8)]})
    b = policy_campaign(tmp_path / "b", {"filter": [(s, int(s < 2), 50.0 + s) for s in range(8)]})
    assert main(["eval", "compare", str(a), f"{b}:filter", "--out", str(tmp_path / "cmp")]) == 0
    printed = capsys.readouterr().out
    assert printed == (tmp_path / "cmp" / "compare.md").read_text()
    data = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    goal = next(r for r in data["outcomes"] if r["name"] == "goal")
    assert (goal["a_only"], goal["b_only"], goal["p_value"]) == (6, 0, pytest.approx(2 / 2**6))
    assert goal["a_interval"][1] == 1.0 and goal["b_interval"][0] < 0.25 < goal["b_interval"][1]
    assert data["a"]["driven"] == ["negobs_gym/OffroadTrack-v0"] and data["pairs"] == 8
    assert sorted(p.name for p in (tmp_path / "cmp").iterdir()) == ["compare.json", "compare.md"]


def test_braking_pairs_by_scenario_and_seed_and_judges_stops_where_there_is_an_obstacle(
    tmp_path: Path,
) -> None:
    def row(scenario: str, flt: str, seed: int, stopped: int, gap: float) -> dict[str, object]:
        start = float("inf") if scenario == "free_track" else 30.0
        key = f"{scenario}.reckless.{int(flt == 'filter')}.{seed:05d}"
        return {"episode": key, "scenario": scenario, "driver": "reckless", "filter": flt, "seed": seed} | {
            "stopped": stopped,
            "entered": 1 - stopped if start < 40 else 0,
            "start_gap_m": start,
            "final_gap_m": gap if start < 40 else start,
            "first_veto_gap_m": float("nan"),
            "vetoes": stopped,
        }

    rows = [row("ditch", "nofilter", s, 0, -1.5) for s in range(3)] + [
        row("ditch", "filter", s, 1, 2.2) for s in range(3)
    ]
    rows += [row("free_track", f, s, 0, 0.0) for f in ("nofilter", "filter") for s in range(3)]
    folder = write_table(tmp_path / "brk" / "braking.csv", BRAKING_COLUMNS, rows)
    with pytest.raises(ConfigError, match=r"holds the groups \['reckless/filter', 'reckless/nofilter'\]"):
        load_side(folder)
    c = compare_campaigns(*load_sides(f"{folder}:reckless/filter"))
    assert c.pairs == 6  # three seeds on each scenario
    rates = {r.name: r for r in c.rates}
    assert (rates["stopped_before"].pairs, rates["stopped_before"].a_only) == (3, 3)  # the ditch's only
    assert rates["vetoed_free_track"].pairs == 3 and rates["collision"].pairs == 6
    gaps = next(s for s in c.shifts if s.name == "final_gap_m")
    assert gaps.pairs == 3 and gaps.median_difference == pytest.approx(3.7)  # the free track's gap is inf
    assert "first_veto_gap_m" not in {s.name for s in c.shifts}  # no finite pair


def test_bad_sides_are_refused_naming_the_problem(tmp_path: Path, capsys) -> None:
    pol = policy_campaign(tmp_path / "pol", {"nofilter": [(0, 1, 1.0)], "filter": [(0, 1, 1.0)]})
    other = policy_campaign(tmp_path / "other", {"filter": [(7, 1, 1.0)]})
    brk = write_table(
        tmp_path / "brk" / "braking.csv", BRAKING_COLUMNS, [{"scenario": "ditch", "start_gap_m": 1}]
    )
    with pytest.raises(ConfigError, match=r"no group 'on'.*holds \['filter', 'nofilter'\]"):
        load_side(pol, "on")
    with pytest.raises(ConfigError, match=r"a policy campaign.*a braking one"):
        compare_campaigns(load_side(pol, "filter"), load_side(brk))
    with pytest.raises(ConfigError, match="share no seed"):
        compare_campaigns(load_side(pol, "filter"), load_side(other))
    with pytest.raises(ConfigError, match="compared with itself"):
        compare_campaigns(load_side(pol, "filter"), load_side(tmp_path / "pol" / ".." / "pol", "filter"))
    with pytest.raises(ConfigError, match=r"holds the groups \['filter'\]: name both sides"):
        load_sides(str(other))
    assert main(["eval", "compare", str(tmp_path)]) == 2
    assert (
        "not a `negobs eval policy|braking --out` or `negobs scenario run --out` folder"
        in capsys.readouterr().err
    )
    old = tmp_path / "old"  # a policy.csv from before the veto_events column
    write_table(old / "policy.csv", tuple(c for c in POLICY_COLUMNS if c != "veto_events"), [{"seed": 0}])
    with pytest.raises(
        ConfigError, match=r"lacks the columns \['veto_events'\]: written by an older version"
    ):
        load_side(old)
    assert split_side(f"{pol}:nofilter") == (pol, "nofilter") and split_side(str(pol)) == (pol, None)
    written = write_comparison(compare_campaigns(*load_sides(str(pol))), tmp_path / "new" / "dir")
    assert [p.exists() for p in written] == [True, True]


def test_scenario_runs_compare_by_driver_and_filter(tmp_path: Path) -> None:
    from negobs_gym.eval.scenario_tables import RESULT_COLUMNS

    def run(folder: str, driver: str, flt: str, stops: list[int]) -> Path:
        rows = [
            {"episode": f"pit_seed{seed}", "scenario": "pit", "seed": seed, "driver": driver, "filter": flt}
            | {"passed": stop, "stopped_before": stop, "entered": 1 - stop, "stop_margin_m": 2.0 + seed}
            for seed, stop in enumerate(stops)
        ]
        return write_table(tmp_path / folder / "results.csv", RESULT_COLUMNS, rows)

    on, off = run("on", "ppo_offroad_nav_v1", "filter", [1] * 7), run("off", "reckless", "nofilter", [0] * 7)
    c = compare_campaigns(*load_sides(str(on), str(off)))
    assert (c.a.kind, c.a.group, c.b.group, c.pairs) == (
        "scenario",
        "ppo_offroad_nav_v1/filter",
        "reckless/nofilter",
        7,
    )
    stops = next(r for r in c.rates if r.name == "stopped_before")
    assert (stops.a_only, stops.p_value) == (7, pytest.approx(2 / 2**7))  # seven seeds, all one way
    assert next(s for s in c.shifts if s.name == "stop_margin_m").median_difference == 0.0


def detection_campaign(folder: Path, recalled: dict[int, list[int]], frames: int = 10) -> Path:
    """A detection campaign's CSVs: per seed, whether the fused detector recalled a 25-cell pit at
    7 m on each of its frames (HDL-64 and HDL-32 alone: never)."""
    folder.mkdir(parents=True)
    obstacles = [
        f"seed{seed:05d},{seed},{k},pit-0,25,7.0,{hit},0,0"
        for seed, hits in recalled.items()
        for k, hit in enumerate(hits)
    ]
    rows = [
        f"seed{seed:05d},{seed},{k},5.0,0.5,0.0,0,0,0,0,0,0,0,0,0" for seed in recalled for k in range(frames)
    ]
    (folder / "obstacles.csv").write_text(",".join(OBSTACLE_COLUMNS) + "\n" + "\n".join(obstacles) + "\n")
    (folder / "frames.csv").write_text(",".join(FRAME_COLUMNS) + "\n" + "\n".join(rows) + "\n")
    return folder


def test_two_detection_campaigns_pair_by_course(tmp_path: Path, capsys) -> None:
    # A recalls the pit on every frame of four courses; B on half of two courses' frames and on
    # every frame of the other two; seed 9 is A's alone
    a = detection_campaign(tmp_path / "a", {s: [1] * 10 for s in (0, 1, 2, 3, 9)})
    b = detection_campaign(tmp_path / "b", {0: [1, 0] * 5, 1: [0, 1] * 5, 2: [1] * 10, 3: [1] * 10})
    c = compare_detection_campaigns(a, b)
    assert (c.courses, c.only_a, c.only_b) == (4, 1, 0)
    fused = c.modes["fused"]
    assert (fused["recall_a"][0], fused["recall_b"][0]) == (1.0, 0.75)  # 6-8 m: 40 of 40, 30 of 40
    assert fused["difference"][0] == pytest.approx(0.25) and fused["recall_a"][1] is None
    low, high = fused["interval"][0]
    # resampling four courses: no half-recalled course (difference 0) up to all four (0.5)
    assert low == pytest.approx(0.0) and high == pytest.approx(0.5) and fused["interval"][1] is None
    assert c.modes["hdl64"]["difference"][0] == 0.0
    assert main(["eval", "compare", str(a), str(b), "--out", str(tmp_path / "cmp")]) == 0
    printed = capsys.readouterr().out
    assert "| 6-8 m | 1.000 | 0.750 | +0.250 | 0.00-0.50 |" in printed
    assert json.loads((tmp_path / "cmp" / "compare.json").read_text())["courses"] == 4


def test_detection_comparisons_refuse_other_drives(tmp_path: Path, capsys) -> None:
    a = detection_campaign(tmp_path / "a", {0: [1] * 10, 1: [1] * 10})
    shorter = detection_campaign(tmp_path / "short", {0: [1] * 5, 1: [1] * 5}, frames=5)
    with pytest.raises(ConfigError, match=r"courses \[0, 1\] ran \[10, 10\] frames"):
        compare_detection_campaigns(a, shorter)
    one = detection_campaign(tmp_path / "one", {0: [1] * 10})
    with pytest.raises(ConfigError, match=r"have 1 course\(s\) in common; resampling needs two"):
        compare_detection_campaigns(a, one)
    with pytest.raises(ConfigError, match="not a `negobs eval detection --out` folder"):
        compare_detection_campaigns(a, tmp_path)
    assert main(["eval", "compare", str(a)]) == 2
    assert "name both folders" in capsys.readouterr().err
