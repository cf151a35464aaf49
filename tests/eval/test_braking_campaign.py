"""Braking campaign: the filter stops the reckless driver before the ditch; summaries from the CSV."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.errors import ConfigError
from negobs_gym.eval.braking_campaign import (
    COLUMNS,
    EPISODE_STEPS,
    SCENARIOS,
    BrakingCampaignConfig,
    ConfigurationSummary,
    episode_overrides,
    episodes,
    obstacle_free,
    report_markdown,
    run_episode,
    scene,
    summarize,
    summary_line,
)
from negobs_gym.eval.campaign import read_csv
from negobs_gym.eval.paths import episode_outcome, task_done
from negobs_gym.eval.vetoes import VETO_COLUMNS
from negobs_gym.safety import braking_distance_m
from negobs_gym.spec import apply_overrides, load_scenario
from tests.helpers import write_vetoes_csv

PNG = b"\x89PNG\r\n\x1a\n"


# slow (end to end): the campaign's summary lines are checked by the module's summarize tests;
# this drives the CLI
@pytest.mark.slow
def test_cli_prints_stopped_before_per_configuration(tmp_path: Path, capsys) -> None:
    out = tmp_path / "braking"
    args = ["eval", "braking", "--seeds", "1", "--scenarios", "ditch,free_track", "--drivers", "reckless"]
    args += ["--free-track-steps", "20"]  # 2 s of free track instead of 15 s: a quicker false-veto check
    assert main(["-q", *args, "--out", str(out), "--no-progress"]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    assert set(lines) == {
        "ditch/reckless/nofilter",
        "ditch/reckless/filter",
        "free_track/reckless/nofilter",
        "free_track/reckless/filter",
    }
    # never braking, the reckless driver enters the ditch; behind the filter it stops before it
    assert "stopped_before=0/1 entries=1/1" in lines["ditch/reckless/nofilter"]
    assert "stopped_before=1/1 entries=0/1" in lines["ditch/reckless/filter"]
    assert " missed_vetoes=0 veto_error_m=" in lines["ditch/reckless/filter"]
    assert "missed_vetoes" not in lines["ditch/reckless/nofilter"]
    assert "false_vetoes_per_km=" in lines["free_track/reckless/filter"]
    # the stopped-before rate's 95 % Wilson interval, where there is an obstacle to stop for
    assert "stopped_before_interval=0.21-1.00" in lines["ditch/reckless/filter"]
    assert "stopped_before_interval" not in lines["free_track/reckless/filter"]
    # the two filter settings episode against episode: the filter alone stopped before the ditch
    assert main(["eval", "compare", f"{out}:reckless/nofilter", f"{out}:reckless/filter"]) == 0
    compared = capsys.readouterr().out
    assert "2 episodes paired by seed" in compared
    assert "| stopped_before | 1 | 0 (0.00-0.79) | 1 (0.21-1.00) | 0 | 1 | -1.00 | 1 |" in compared
    summaries = [ConfigurationSummary(**d) for d in json.loads((out / "summary.json").read_text())]
    ditch = next(s for s in summaries if s.name == "ditch/reckless/filter")
    assert len(ditch.stop_margins_m) == 1 and ditch.stop_margins_m[0] > 0
    assert len(ditch.first_veto_gaps_m) == 1 and ditch.first_veto_gaps_m[0] > ditch.stop_margins_m[0]
    assert ditch.first_veto_gaps_m[0] < 12.0  # the gap when it first braked, not at the start (20-40 m)
    for png in ("stop_margins.png", "first_veto.png", "veto_errors.png"):
        assert (out / png).read_bytes()[:8] == PNG
    # every step's pose in paths.csv; `negobs eval paths` draws the runs that did not do their task
    rows = {r["episode"]: r for r in read_csv(out / "braking.csv")}
    paths = read_csv(out / "paths.csv")
    for key, row in rows.items():
        steps = [p for p in paths if p["episode"] == key]
        assert [int(p["step"]) for p in steps] == list(range(int(row["steps"]) + 1))
        assert sum(p["vetoed"] == "1" for p in steps) == int(row["vetoes"])
        assert sum(p["missed_veto"] == "1" for p in steps) == int(row["missed_vetoes"])
    # the filter's vetoes for the ditch are for the ditch; on the free track, any is false
    assert (
        int(rows["ditch.reckless.1.00000"]["vetoes"]) > 0
        and rows["ditch.reckless.1.00000"]["false_vetoes"] == "0"
    )
    free = rows["free_track.reckless.1.00000"]
    assert (
        free["false_vetoes"] == free["vetoes"] and rows["free_track.reckless.0.00000"]["false_vetoes"] == "0"
    )
    assert {r["missed_vetoes"] for r in rows.values()} == {"0"}  # stopped in time, or no filter to miss
    # the ditch's vetoes put its near edge within a grid cell or two of the true rim; nothing to
    # judge without vetoes, or where each is false
    ditch_error = float(rows["ditch.reckless.1.00000"]["max_veto_error_m"])
    assert abs(ditch_error) < 0.5 and ditch.max_veto_error_m == ditch_error
    median, onset = np.median(ditch.veto_errors_m), np.median(ditch.onset_veto_errors_m)
    medians = f" median_veto_error_m={median:+.2f} median_onset_veto_error_m={onset:+.2f}"
    assert lines["ditch/reckless/filter"].endswith(f" veto_error_m={ditch_error:+.2f}{medians}")
    assert math.isnan(float(free["max_veto_error_m"]))
    # vetoes.csv: each veto (and missed veto) of the filtered runs, judged on the ground truth
    vetoes = read_csv(out / "vetoes.csv")
    assert list(vetoes[0]) == list(VETO_COLUMNS)
    for key, row in rows.items():
        judged = [v for v in vetoes if v["episode"] == key]
        assert sum(v["kind"] == "veto" for v in judged) == int(row["vetoes"])
        assert sum(v["kind"] == "missed" for v in judged) == int(row["missed_vetoes"])
        assert sum(v["false_veto"] == "1" for v in judged) == int(row["false_vetoes"])
        # an onset is a veto whose step before was no veto: one per braking event
        vetoed = {int(v["step"]) for v in judged if v["kind"] == "veto"}
        onsets = [int(v["step"]) for v in judged if v["onset"] == "1"]
        assert onsets == sorted(s for s in vetoed if s - 1 not in vetoed)
        assert len(onsets) == int(row["veto_events"])
        errors = [float(v["error_m"]) for v in judged if not math.isnan(float(v["error_m"]))]
        assert max(errors, default=math.nan) == pytest.approx(float(row["max_veto_error_m"]), nan_ok=True)
        steps = [p for p in paths if p["episode"] == key]
        for v in judged:  # the step it decided at, the speed of the step before, R(v) of Eq. 18
            assert steps[int(v["step"])]["vetoed"] == "1"
            before_mps = max(0.0, float(steps[int(v["step"]) - 1]["speed_mps"]))  # forward speed
            assert float(v["speed_mps"]) == pytest.approx(before_mps, abs=1e-6)
            assert float(v["braking_distance_m"]) == pytest.approx(
                float(braking_distance_m(float(v["speed_mps"]))), abs=1e-5
            )
            assert float(v["applied_longitudinal"]) < float(v["proposed_longitudinal"])  # it braked
    ditch_vetoes = [v for v in vetoes if v["episode"] == "ditch.reckless.1.00000"]
    assert [float(v["error_m"]) for v in ditch_vetoes] == pytest.approx(ditch.veto_errors_m, abs=1e-6)
    onset_errors = [float(v["error_m"]) for v in ditch_vetoes if v["onset"] == "1"]
    assert onset_errors == pytest.approx(ditch.onset_veto_errors_m, abs=1e-6) and len(onset_errors) >= 1
    assert all(float(v["true_distance_m"]) < float(v["hazard_distance_m"]) + 0.5 for v in ditch_vetoes)
    free_vetoes = [v for v in vetoes if v["episode"] == "free_track.reckless.1.00000"]
    assert all(v["false_veto"] == "1" and v["error_m"] == "nan" for v in free_vetoes)  # nothing there
    assert not [v for v in vetoes if v["filter"] == "nofilter"]
    assert math.isnan(float(rows["ditch.reckless.0.00000"]["max_veto_error_m"]))
    assert int(rows["free_track.reckless.0.00000"]["steps"]) == 20  # never stops without the filter
    assert int(rows["free_track.reckless.1.00000"]["steps"]) <= 20
    assert main(["-q", "eval", "paths", str(out)]) == 0
    drawn = [Path(p).stem for p in capsys.readouterr().out.split()]
    ditch_keys = sorted(k for k in rows if k.startswith("ditch."))
    assert "ditch.reckless.0.00000" in drawn and "ditch.reckless.1.00000" not in drawn  # entered / stopped
    assert drawn == sorted(k for k, r in rows.items() if not task_done(r))
    assert (
        episode_outcome(rows[ditch_keys[0]]) == "entered"
        and episode_outcome(rows[ditch_keys[1]]) == "stopped"
    )
    assert (out / "paths" / "ditch.reckless.0.00000.png").read_bytes()[:8] == PNG
    # `negobs eval video` replays the episode that entered the ditch, checked against its rows
    if importlib.util.find_spec("imageio_ffmpeg") is not None:
        assert main(["-q", "eval", "video", str(out), "--episode", "ditch.reckless.0.00000"]) == 0
        assert capsys.readouterr().out.split() == [str(out / "videos" / "ditch.reckless.0.00000.mp4")]
        assert (out / "videos" / "ditch.reckless.0.00000.mp4").stat().st_size > 0
        model = ["--model", "ppo_offroad_nav_v1"]  # a scripted driver's episode ran no model
        assert main(["eval", "video", str(out), "--episode", "ditch.reckless.0.00000", *model]) == 2
        assert "ran a scripted driver, no model" in capsys.readouterr().err


def test_summarize_counts_hand_made_rows(tmp_path: Path) -> None:
    def row(scenario, flt, seed, entered, stopped, final_gap, veto_gap, events, dist, missed=0, error="nan"):
        values = [
            f"{scenario}.r.{seed}",
            scenario,
            "reckless",
            flt,
            seed,
            100,
            dist,
            dist,
            entered,
            0,
            0,
            0,
            0,
        ]
        return ",".join(
            str(v) for v in [*values, stopped, 30.0, final_gap, veto_gap, 3, events, 0, missed, error, 3.0]
        )

    csv = tmp_path / "b.csv"
    rows = [
        row("ditch", "filter", 0, 0, 1, 2.5, 9.0, 1, 26.0, error=-0.2),
        row("ditch", "filter", 1, 1, 0, -1.0, 4.0, 1, 31.0, missed=4, error=1.75),
        row("free_track", "filter", 0, 0, 0, "inf", "nan", 2, 500.0),
        row("free_track", "filter", 1, 0, 0, "inf", "nan", 0, 500.0),
    ]
    csv.write_text(",".join(COLUMNS) + "\n" + "\n".join(rows) + "\n")
    ditch, free = summarize(csv)
    assert (ditch.episodes, ditch.entries, ditch.stopped_before) == (2, 1, 1)
    assert ditch.stop_margins_m == [2.5] and ditch.first_veto_gaps_m == [9.0, 4.0]
    assert ditch.false_vetoes_per_km is None
    assert free.false_vetoes_per_km == pytest.approx(2.0) and free.stopped_before == 0
    assert summary_line(ditch).startswith("ditch/reckless/filter stopped_before=1/2")
    assert ditch.missed_vetoes == 4 and summary_line(ditch).endswith(" missed_vetoes=4 veto_error_m=+1.75")
    assert free.max_veto_error_m is None  # no veto with a true hazard to judge by
    assert "| 4 |" in report_markdown([ditch])
    assert ditch.veto_errors_m == [] and ditch.median_veto_error_m is None  # no vetoes.csv read
    # with vetoes.csv: every judged veto's error, per configuration (missed and unjudged skipped)
    vetoes = tmp_path / "vetoes.csv"
    nan = float("nan")
    judged = [("ditch.r.0", "veto", -0.2), ("ditch.r.1", "veto", 1.75, False), ("ditch.r.1", "veto", 0.1)]
    judged += [("ditch.r.1", "missed", nan), ("ditch.r.1", "veto", nan), ("free_track.r.0", "veto", nan)]
    write_vetoes_csv(vetoes, [(key, "filter", *judgement) for key, *judgement in judged])
    ditch, free = summarize(csv, vetoes)
    assert ditch.veto_errors_m == [-0.2, 1.75, 0.1] and ditch.median_veto_error_m == pytest.approx(0.1)
    assert ditch.onset_veto_errors_m == [-0.2, 0.1]  # the held veto (onset 0) left out
    assert ditch.median_onset_veto_error_m == pytest.approx(-0.05)
    assert free.veto_errors_m == [] and free.median_veto_error_m is None
    assert free.median_onset_veto_error_m is None
    assert summary_line(ditch).endswith(
        " veto_error_m=+1.75 median_veto_error_m=+0.10 median_onset_veto_error_m=-0.05"
    )
    assert "| 4 | 0.100 | -0.050 | 1.750 |" in report_markdown([ditch])  # missed, medians, largest
    write_vetoes_csv(vetoes, [("trench.r.0", "filter", "veto", 0.1)])  # another campaign's
    with pytest.raises(ConfigError, match=r"vetoes_csv.*'trench.r.0'.*not the same campaign's"):
        summarize(csv, vetoes)


def test_configurations_are_data() -> None:
    cfg = BrakingCampaignConfig(seeds=2, scenarios=("ditch", "pit_100x50"), drivers=("reckless",))
    keys = [e.key for e in episodes(cfg)]
    assert len(keys) == 2 * 1 * 2 * 2 == len(set(keys))
    assert {"ditch", "pit_100x50", "trench_narrow", "pit_offcentre", "free_track"} <= set(SCENARIOS)
    with pytest.raises(ConfigError, match="scenarios"):
        BrakingCampaignConfig(scenarios=("moon",))
    with pytest.raises(ConfigError, match="model_path"):
        BrakingCampaignConfig(drivers=("sb3",))


def test_free_track_steps_bounds_only_the_free_track_episodes() -> None:
    assert BrakingCampaignConfig().free_track_steps == EPISODE_STEPS == 150  # the 15 s limit at 10 Hz
    for bad in (0, -1, EPISODE_STEPS + 1, 2.5, True, "20"):
        with pytest.raises(ConfigError, match="free_track_steps"):
            BrakingCampaignConfig(free_track_steps=bad)
    scenarios, drivers = ("ditch", "free_track"), ("reckless",)
    cfg = BrakingCampaignConfig(
        seeds=1, scenarios=scenarios, drivers=drivers, filters=(False,), free_track_steps=3
    )
    ditch, free = episodes(cfg)
    assert "max_steps" not in ditch.args and free.args["max_steps"] == 3  # recorded in the free track's part
    default = episodes(dataclasses.replace(cfg, free_track_steps=EPISODE_STEPS))
    assert all("max_steps" not in e.args for e in default)  # parts as before the field: resumable
    rows = run_episode(free)
    (row,) = _read_rows(rows["braking"])
    assert row["scenario"] == "free_track" and row["steps"] == "3" and float(row["distance_m"]) > 0
    assert len(rows["paths"]) == 3 + 1  # the reset's pose and one per step


def _read_rows(lines: list[str]) -> list[dict[str, str]]:
    """Formatted rows of :data:`COLUMNS` as dicts, as ``read_csv`` gives them."""
    return [dict(zip(COLUMNS, line.split(","), strict=True)) for line in lines]


def _episode_spec(episode):
    """The scene an episode of the campaign runs on, every override applied."""
    return apply_overrides(scene(episode.args["scenario"]), episode_overrides(episode.args))


def test_each_scenario_is_a_shipped_scene_of_braking_v0s_episode() -> None:
    """The scenes hold what the campaign's scenarios always were: Braking-v0's 25 km/h start and
    15 s on their terrain, the obstacle's near edge 20-40 m ahead; only free_track has none."""
    braking = load_scenario("braking_v0")
    for scenario in SCENARIOS:
        spec = load_scenario(f"braking_campaign_{scenario}")
        assert spec == scene(scenario) and spec.name == f"braking_campaign_{scenario}"
        assert spec.start == braking.start and spec.episode == braking.episode
        assert spec.observation == braking.observation and spec.terminations == braking.terminations
        assert spec.episode.max_episode_steps == EPISODE_STEPS
        params = spec.terrain.params
        if obstacle_free(scenario):
            assert spec.terrain.preset == "rough_track" and scenario == "free_track"
        else:
            assert spec.terrain.preset == "braking_track"
            assert (params["ditch_distance_m"].low, params["ditch_distance_m"].high) == (20.0, 40.0)
    assert scene("pit_offcentre").terrain.params["lateral_offset_m"] == 0.8
    assert (
        scene("trench_narrow").terrain.params["ditch_length_m"],
        scene("ditch").terrain.params["ditch_width_m"],
    ) == (
        0.4,
        3.0,
    )


def test_overrides_reach_every_episodes_scene_after_the_campaigns_oracle() -> None:
    """``overrides`` (the --set paths) change every scene; a scripted driver's episode runs on the
    oracle grid unless they say otherwise, the model's on the scene's detector grid."""
    cfg = BrakingCampaignConfig(seeds=1, scenarios=("ditch",), drivers=("reckless",), filters=(True,))
    (plain,) = episodes(cfg)
    assert "overrides" not in plain.args  # a default campaign's parts as before
    assert _episode_spec(plain).observation.source == "oracle"
    assert _episode_spec(plain).observation.tighten_pairs is True  # the envs' default
    changed = ("observation.tighten_pairs=false", "observation.rig=native", "observation.source=detector")
    (episode,) = episodes(dataclasses.replace(cfg, overrides=changed))
    assert episode.args["overrides"] == list(changed)
    observation = _episode_spec(episode).observation
    assert (observation.tighten_pairs, observation.rig, observation.source) == (False, "native", "detector")
    sb3 = {**plain.args, "driver": "sb3"}
    assert apply_overrides(scene("ditch"), episode_overrides(sb3)).observation.source == "detector"
    for bad, field in [
        (("observation.tighten_pairs='yes'",), "observation.tighten_pairs"),
        (("observation.rig=moon",), "observation.rig"),
        (("observation.scan_every=0",), "observation.scan_every"),
        (("episode.time_limt_s=3",), "time_limt_s"),
        (("no_equals_sign",), "--set"),
    ]:
        with pytest.raises(ConfigError, match=field):
            BrakingCampaignConfig(overrides=bad)
    with pytest.raises(ConfigError, match="overrides"):
        BrakingCampaignConfig(overrides="observation.rig=native")  # one text, not a tuple of them


def test_the_old_scene_fields_warn_and_become_overrides() -> None:
    """The fields the config once copied from the scenes work for one release, as their paths."""
    with pytest.warns(DeprecationWarning, match="overrides="):
        old = BrakingCampaignConfig(
            rig="native", tighten_pairs=False, overrides=("observation.scan_every=2",)
        )
    assert old.overrides == (
        'observation.rig="native"',
        "observation.tighten_pairs=false",
        "observation.scan_every=2",
    )
    assert "rig" not in {f.name for f in dataclasses.fields(old)}  # no copy kept
    with pytest.raises(ConfigError, match="scan_far_from_m"), pytest.warns(DeprecationWarning):
        BrakingCampaignConfig(scan_every=3, scan_far_from_m=40.0)  # beyond the grid, named by its path


def test_scan_every_reaches_the_episode_and_the_filter_allows_the_frames_age() -> None:
    """A filtered reckless episode with a frame every 3 steps (hazards up to 0.2 s old, from which
    the filter's timeout counts) vetoes by distance, not by staleness, and stops before the ditch."""
    cfg = BrakingCampaignConfig(
        seeds=1,
        scenarios=("ditch",),
        drivers=("reckless",),
        filters=(True,),
        overrides=("observation.scan_every=3",),
    )
    (episode,) = episodes(cfg)
    assert _episode_spec(episode).observation.scan_every == 3
    (row,) = _read_rows(run_episode(episode)["braking"])
    assert row["entered"] == "0" and row["stopped"] == "1"
    assert 0 < float(row["final_gap_m"]) and float(row["first_veto_gap_m"]) < 16.0  # vetoed by distance


def test_scan_far_from_m_reaches_the_episodes_observation_and_is_checked() -> None:
    far = ("observation.scan_every=3", "observation.scan_far_from_m=12.0")
    cfg = BrakingCampaignConfig(seeds=1, scenarios=("ditch",), drivers=("reckless",), overrides=far)
    observation = _episode_spec(episodes(cfg)[0]).observation
    assert observation.scan_far_from_m == 12.0 and observation.scan_every == 3
    for bad in ("40.0", "nan", '"12"'):
        with pytest.raises(ConfigError, match="scan_far_from_m"):
            BrakingCampaignConfig(
                overrides=("observation.scan_every=3", f"observation.scan_far_from_m={bad}")
            )
