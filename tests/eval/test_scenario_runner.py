"""run_scenario: a researcher's scripted scenario test, with and without the safety filter."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from negobs_gym.drivers import RecklessDriver
from negobs_gym.errors import ConfigError
from negobs_gym.eval.scenario_runner import ScenarioResult, check_criteria, run_scenario, run_scenario_seeds
from negobs_gym.eval.vetoes import FALSE_VETO_TOLERANCE_M, VetoJudgement
from negobs_gym.safety import SafetyFilterConfig
from negobs_gym.spec import load_scenario, spec_from_toml, spec_to_toml
from negobs_gym.spec.overrides import apply_overrides
from negobs_gym.spec.scenario import CriteriaSpec
from tests.helpers import PIT_SCENE


@pytest.fixture(scope="module")
def runs() -> dict[bool, list[ScenarioResult]]:
    spec = spec_from_toml(PIT_SCENE)
    return {
        f: [run_scenario(spec, RecklessDriver(), filter=f, seed=s) for s in range(3)] for f in (False, True)
    }


def test_reckless_driver_enters_the_pit_without_the_filter_and_stops_before_it_with(runs, tmp_path) -> None:
    """One test reads the module's runs (a module fixture is built once per xdist worker): without
    the filter, with it, and a video of a filtered episode."""
    for r in runs[False]:
        assert r.entered_negative_obstacle and not r.stopped_before and r.stop_margin_m is None
        assert r.vetoes == 0 and not r.filtered and not r.task_done
        assert r.termination == ("entered_negative_obstacle",)
        assert set(r.failures) >= {"entered_negative_obstacle", "stopped_before"} and not r.passed
    # the filter stops it before the pit on every seed
    starts = {round(r.start_gap_m, 6) for r in runs[True]}
    assert len(starts) == 3  # the station is drawn per seed
    for r, plain in zip(runs[True], runs[False], strict=True):
        assert r.start_gap_m == plain.start_gap_m  # same seed, same pit
        assert not r.entered_negative_obstacle and r.stopped_before
        assert 0.5 < r.stop_margin_m < 8.0
        assert r.vetoes > 0 and r.false_vetoes == 0
        assert r.max_decel_mps2 > 4.0  # a real brake (mu g = 6.4 m/s^2 with locked wheels)
        assert r.termination == ("stopped",) and r.passed and r.task_done and not r.left_track
        assert not r.collision and not r.goal_reached and r.time_s < 9.0
    _check_a_video_of_the_episode_leaves_the_episode_as_it_was(runs[True][0], tmp_path)


# a 3 x 3 m pit 16 m on and 5 m left of the start line, the filter's cells held 2 s
TURN_SCENE = """
name = "pit_left_in_a_turn"
terminations = ["entered_negative_obstacle", "trapped", "collision", "rollover", "stopped"]
[terrain.course]
length_m = 45.0
[[obstacles]]
kind = "pit"
length_m = 3.0
width_m = 3.0
depth_m = 0.6
station_m = 16.0
lateral_m = -5.0
[start]
speed_mps = 5.0
[episode]
time_limit_s = 8.0
[observation]
hazard_hold_s = 2.0
"""


class _SteadyLeftTurn:
    """Full throttle, steering 0.3 of full lock to the left: towards the pit beside the line."""

    def reset(self, seed: int) -> None:
        pass

    def act(self, obs, info) -> np.ndarray:
        return np.array([1.0, 0.3], np.float32)


def test_vetoes_are_judged_along_the_corridor_the_filter_searched() -> None:
    """Turning towards a pit, the filter vetoes for it while it lies beside the straight line
    ahead: judged against the ground truth straight ahead, 16 of these 20 vetoes were counted
    false; judged along the steering's arc, none is. Holding the pit's cells, it misses none."""
    r = run_scenario(spec_from_toml(TURN_SCENE), _SteadyLeftTurn(), filter=True, seed=0)
    assert not r.entered_negative_obstacle and r.termination == ("stopped",)
    assert r.vetoes >= 10 and r.false_vetoes == 0 and r.missed_vetoes == 0
    # it stands before the pit on its arc, none lies straight ahead: the margin is taken along
    # the arc the driver still steers
    assert r.stopped_before and 0.5 < r.stop_margin_m < 4.0
    # the held cells keep the near rim where it was seen: each veto put it at most ~0.4 m off
    assert r.max_veto_error_m is not None and abs(r.max_veto_error_m) < 0.5


PIT_BESIDE_THE_LINE = """
name = "pit_beside_the_line"
terminations = ["entered_negative_obstacle", "trapped", "collision", "rollover", "stopped"]
[terrain.course]
length_m = 45.0
[[obstacles]]
kind = "pit"
length_m = 2.0
width_m = 2.0
depth_m = 0.6
station_m = 20.0
lateral_m = 1.8
[start]
speed_mps = 5.0
[episode]
time_limit_s = 7.0
"""


def test_with_a_steering_search_the_filter_steers_off_a_pit_beside_the_line_instead_of_stopping() -> None:
    """The reckless driver at 25 km/h on a line whose corridor clips a pit's edge: the braking
    filter stops it ~13 m in; a filter that may change the steering by 0.3 steers it off the
    pit while the pit is still beyond the stopping distance (the steering lead), and it drives
    the whole course without a veto or an entry."""
    spec = spec_from_toml(PIT_BESIDE_THE_LINE)
    braking = run_scenario(spec, "reckless", filter=spec.filter, seed=0)
    search = dataclasses.replace(spec.filter, steer_search=0.3)
    r = run_scenario(spec, "reckless", filter=search, seed=0)
    assert braking.steered_steps == 0 and braking.termination == ("stopped",) and braking.progress_m < 15.0
    assert r.steered_steps > 0 and f" steered={r.steered_steps} " in r.line()
    assert r.metrics()["steered_steps"] == r.steered_steps  # a policy campaign's column
    assert not r.entered_negative_obstacle and r.truncated and r.progress_m > 40.0
    assert r.vetoes == 0 and braking.vetoes > 0


def test_missed_vetoes_count_the_steps_the_filter_let_into_a_hazard() -> None:
    """The same turn as paper N's filter reads it, each frame alone: creeping on after its stop,
    the pit's cells leave the grid as its rim nears the front bumper, the corridor looks clear, and
    the car drives in; every step let through with the pit 2 m inside R(v) is a missed veto."""
    spec = spec_from_toml(TURN_SCENE.replace("hazard_hold_s = 2.0", "hazard_hold_s = 0.0"))
    spec = dataclasses.replace(spec, criteria=CriteriaSpec(max_missed_vetoes=0))
    r = run_scenario(spec, _SteadyLeftTurn(), filter=SafetyFilterConfig(), seed=0)  # no memory
    assert r.entered_negative_obstacle and r.vetoes > 0 and r.false_vetoes == 0
    assert r.missed_vetoes >= 3 and r.failures == ("max_missed_vetoes",)
    # read frame by frame, the near rim leaves the sensors' view first: the filter put the pit
    # farther than it was, by most of a metre at its later vetoes
    assert r.max_veto_error_m > 0.5 and " veto_error_m=+" in r.line()
    late = dataclasses.replace(spec, criteria=CriteriaSpec(max_veto_error_m=0.5))
    assert check_criteria(late.criteria, r) == ("max_veto_error_m",)
    assert len(r.missed_steps) == r.missed_vetoes and not set(r.missed_steps) & set(r.vetoed_steps)
    assert max(r.missed_steps) > max(r.vetoed_steps)  # after its stop, on the way in
    # each judgement says how: the first veto saw the rim where it was, the later ones farther
    # (the near rim leaving view), and on the way in nothing was detected at all (d = inf)
    vetoes = [j for j in r.veto_judgements if j.vetoed]
    missed = [j for j in r.veto_judgements if not j.vetoed]
    assert [j.step for j in vetoes] == list(r.vetoed_steps)
    assert [j.step for j in missed] == list(r.missed_steps)
    assert abs(vetoes[0].error_m) < 0.5 and max(j.error_m for j in vetoes) == r.max_veto_error_m
    assert all(math.isinf(j.hazard_distance_m) for j in missed)
    assert all(j.true_distance_m + FALSE_VETO_TOLERANCE_M < j.braking_distance_m for j in missed)
    assert all(j.applied_action == j.proposed_action for j in missed)
    assert f" missed_vetoes={r.missed_vetoes} " in r.line()
    plain = run_scenario(spec, _SteadyLeftTurn(), filter=False, seed=0)
    assert plain.entered_negative_obstacle and plain.missed_vetoes == 0  # no filter, nothing to miss
    # the scenes' default filter keeps the pit in its hazard memory: the car stays out
    kept = run_scenario(spec, _SteadyLeftTurn(), filter=True, seed=0)
    assert not kept.entered_negative_obstacle and kept.missed_vetoes == 0


def _veto(step: int, hazard_m: float, truth_m: float, false_veto: bool = False) -> VetoJudgement:
    """A judged veto at 6 m/s (R(v) 8 m) that braked."""
    return VetoJudgement(
        step=step, vetoed=True, speed_mps=6.0, braking_distance_m=8.0, hazard_distance_m=hazard_m,
        true_distance_m=truth_m, channel="negative", false_veto=false_veto, perception_stale=False,
        proposed_action=(1.0, 0.0), applied_action=(-1.0, 0.0), onset=step == 1,
    )  # fmt: skip


def test_criteria_check_each_named_bound() -> None:
    # three vetoes, one false (nothing there), the largest error 5.5 - 5.0 m
    judged = (_veto(1, 5.5, 5.0), _veto(2, 4.0, 4.0), _veto(3, 3.0, math.inf, false_veto=True))
    result = ScenarioResult(
        scenario="x", seed=0, driver="d", filtered=True, steps=10, time_s=1.0, distance_m=5.0,
        progress_m=5.0, entered_negative_obstacle=False, stopped=False, stopped_before=True,
        stop_margin_m=2.0, start_gap_m=20.0, final_gap_m=2.0, first_veto_gap_m=9.0, collision=False,
        trapped=False, rollover=False, goal_reached=False, off_track_steps=0, task_done=True,
        max_decel_mps2=6.0, positive_gap_m=3.0, final_speed_mps=0.0, cost=0.0,
        termination=("stopped",), truncated=False, veto_judgements=judged,
    )  # fmt: skip
    assert (result.vetoes, result.false_vetoes, result.max_veto_error_m, result.veto_events) == (3, 1, 0.5, 1)
    assert check_criteria(CriteriaSpec(), result) == ()
    assert check_criteria(CriteriaSpec(task_done=False), result) == ("task_done",)
    assert check_criteria(CriteriaSpec(min_stop_margin_m=2.5, max_stop_margin_m=3.0), result) == (
        "min_stop_margin_m",
    )
    assert check_criteria(CriteriaSpec(max_veto_error_m=0.5), result) == ()
    assert check_criteria(CriteriaSpec(max_veto_error_m=0.3), result) == ("max_veto_error_m",)
    unjudged = dataclasses.replace(result, veto_judgements=judged[2:])  # no veto with a true hazard
    assert unjudged.max_veto_error_m is None
    assert check_criteria(CriteriaSpec(max_veto_error_m=0.0), unjudged) == ()
    assert check_criteria(CriteriaSpec(max_false_vetoes=0, max_vetoes=3, max_time_s=0.5), result) == (
        "max_false_vetoes",
        "max_time_s",
    )
    assert check_criteria(CriteriaSpec(max_missed_vetoes=0), result) == ()
    missed = [dataclasses.replace(_veto(step, math.inf, 3.0), vetoed=False) for step in (4, 5)]
    two_missed = dataclasses.replace(result, veto_judgements=(*judged, *missed))
    assert two_missed.missed_steps == (4, 5) and two_missed.vetoed_steps == (1, 2, 3)
    assert check_criteria(CriteriaSpec(max_missed_vetoes=1), two_missed) == ("max_missed_vetoes",)
    assert check_criteria(CriteriaSpec(max_decel_mps2=5.0, goal_reached=True), result) == (
        "goal_reached",
        "max_decel_mps2",
    )
    assert check_criteria(CriteriaSpec(min_positive_gap_m=3.5), result) == ("min_positive_gap_m",)
    assert check_criteria(CriteriaSpec(min_positive_gap_m=3.0), result) == ()
    assert check_criteria(CriteriaSpec(left_track=True), result) == ("left_track",)
    assert "positive_gap_m=3.00" in result.line()
    none = dataclasses.replace(result, stop_margin_m=None, stopped_before=False, positive_gap_m=math.inf)
    assert check_criteria(CriteriaSpec(min_stop_margin_m=0.0, stopped_before=False), none) == (
        "min_stop_margin_m",
    )
    assert "margin_m=-" in none.line() and "positive_gap_m=-" in none.line()


def test_a_spec_can_name_the_track_planner_at_its_target_speed() -> None:
    from negobs_gym.drivers import TrackPlannerDriver
    from negobs_gym.eval.scenario_runner import make_driver
    from negobs_gym.sim.presets import braking_track
    from negobs_gym.spec.library import load_scenario

    spec = load_scenario("offroad_nav_v2")
    run = dataclasses.replace(spec.run, driver="track_planner", target_speed_mps=3.0)
    spec = dataclasses.replace(spec, run=run)
    driver = make_driver(spec.run.driver, spec, braking_track(20.0, rough=False))
    assert isinstance(driver, TrackPlannerDriver)
    assert driver.config.pursuit.target_speed_mps == 3.0


def test_the_filter_stops_for_a_rock_only_when_told() -> None:

    told = run_scenario("rock_on_track_25kmh", seed=0)  # the spec's run: reckless, stop_for_positive
    assert told.passed, told.line()
    assert not told.collision and told.termination == ("stopped",)
    assert 1.0 < told.positive_gap_m < 6.0  # B = 5 m from the rear axle, ~3.4 m behind the bumper
    assert told.vetoes > 0 and told.false_vetoes == 0 and told.max_decel_mps2 > 4.0
    path = np.asarray(told.path_xy_m)  # the reset's position, then one per step
    assert path.shape == (told.steps + 1, 2) and len(told.vetoed_steps) == told.vetoes
    assert list(told.vetoed_steps) == sorted(set(told.vetoed_steps)) and told.vetoed_steps[-1] <= told.steps
    assert np.hypot(*np.diff(path, axis=0).T).max() < 25 / 3.6 * 0.1 + 0.05  # <= 25 km/h for 0.1 s

    papers = run_scenario("rock_on_track_25kmh", filter=SafetyFilterConfig(), seed=0)  # used as it is
    assert papers.collision and papers.vetoes == 0 and "collision" in papers.failures


# slow (end to end): the filter's steered corridor is checked by tests/safety/test_corridor.py and
# test_filter.py
@pytest.mark.slow
def test_the_filter_stops_for_a_pit_in_a_bend_where_the_car_turns() -> None:
    """Pure pursuit follows a 30 m radius bend at 25 km/h, steering left all the way; the filter
    judges the pit under its inner wheels along that arc and stops before it. Without the filter
    the car drives in."""
    r = run_scenario("pit_in_a_bend_25kmh", seed=0)
    assert r.passed, r.line()
    assert r.stopped_before and 1.0 < r.stop_margin_m < 4.0 and r.vetoes > 10
    assert r.max_veto_error_m is not None and abs(r.max_veto_error_m) < 0.5
    plain = run_scenario("pit_in_a_bend_25kmh", filter=False, seed=0)
    assert plain.entered_negative_obstacle and "entered_negative_obstacle" in plain.failures


@pytest.mark.parametrize("zoom_m", [0.0, -2.0, math.nan, math.inf])
def test_a_bad_draw_window_is_named_before_the_episode_runs(zoom_m, tmp_path) -> None:
    with pytest.raises(ConfigError, match="draw_zoom_m"):
        run_scenario(spec_from_toml(PIT_SCENE), draw_to=tmp_path / "x.png", draw_zoom_m=zoom_m)
    assert not (tmp_path / "x.png").exists()


# slow (end to end): scenario seeds in two processes; two workers against one process is checked
# by tests/eval/test_detection_campaign.py's resume test and the vector-env tests
@pytest.mark.slow
def test_seeds_in_two_processes_give_the_serial_results_in_seed_order(runs, tmp_path) -> None:
    spec = spec_from_toml(PIT_SCENE)
    # run_scenario in this process, seeds 1 and 0 (its driver named by its class, not "reckless")
    serial = [dataclasses.replace(runs[True][k], driver="reckless") for k in (1, 0)]
    spread = list(run_scenario_seeds(spec, "reckless", [1, 0], filter=True, workers=2, draw_dir=tmp_path))
    assert spread == serial  # every field, the path included: a seed's episode is the seed's alone
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"pit_0.6m_seed{k}.png" for k in range(2)]
    with pytest.raises(ConfigError, match="workers"):
        run_scenario_seeds(spec, "reckless", [0], workers=0)


def _check_a_video_of_the_episode_leaves_the_episode_as_it_was(seed_0: ScenarioResult, tmp_path) -> None:
    """The filtered seed-0 episode again, filmed: the same result, a frame per step, red when vetoed."""
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    path = tmp_path / "pit.mp4"
    result = run_scenario(spec_from_toml(PIT_SCENE), RecklessDriver(), filter=True, seed=0, video_to=path)
    assert result == seed_0
    reader = imageio_ffmpeg.read_frames(str(path))
    w, h = next(reader)["size"]
    frames = [np.frombuffer(b, np.uint8).reshape(h, w, 3) for b in reader]
    assert len(frames) == result.steps + 1  # after the reset and after every step
    border = np.array([f[2, -3].astype(int) for f in frames[1:]])  # the local panel's right border
    vetoed = np.all(np.abs(border - (230, 0, 0)) < 40, axis=1)
    assert vetoed.sum() == result.vetoes  # a red border for every vetoed step, green otherwise
    with pytest.raises(ConfigError, match="render_mode"):
        run_scenario(spec_from_toml(PIT_SCENE), render_mode="human", video_to=path)


def test_a_specs_driver_settings_reach_its_scripted_driver_and_a_bad_one_names_run() -> None:
    from negobs_gym.eval.scenario_runner import make_driver
    from negobs_gym.sim.presets import braking_track
    from negobs_gym.spec.library import load_scenario
    from negobs_gym.spec.overrides import apply_overrides

    spec = apply_overrides(load_scenario("offroad_nav_v2"), ["run.driver_settings.planner.bend_steps=1"])
    assert spec_from_toml(spec_to_toml(spec)) == spec  # kept in the run's scenario.toml
    driver = make_driver("grid_planner", spec, braking_track(20.0, rough=False))
    assert driver.config.planner.bend_steps == 1
    assert driver.config.planner.pursuit.target_speed_mps == spec.run.target_speed_mps
    bad = apply_overrides(spec, ["run.driver_settings.planner.bend_steps=-1"])
    with pytest.raises(ConfigError, match=r"^run\.driver_settings: .*bend_steps"):
        make_driver("grid_planner", bad, braking_track(20.0, rough=False))


def test_the_steering_search_never_steers_the_car_into_the_ditch_it_would_have_braked_for() -> None:
    """The reckless driver at 25 km/h at a ditch across the track, behind a filter that may steer
    by 0.3 with no margin: a search that steered in place of the veto drove this seed into the
    ditch (the car's yaw rate builds over 0.1-0.7 s, so the arc it found at the boundary was not
    driven); steering only ahead of the boundary, it stops before the ditch."""
    settings = ["filter.steer_search=0.3", "filter.margin_m=0", "episode.time_limit_s=8"]
    spec = apply_overrides(load_scenario("braking_v0"), settings)
    r = run_scenario(spec, "reckless", filter=spec.filter, seed=1)
    assert r.steered_steps > 0 and r.vetoes > 0
    assert not r.entered_negative_obstacle and r.stopped_before and r.stop_margin_m > 0.5
