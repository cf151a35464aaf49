"""``negobs scenario``: list, show, run (one line per seed, exit 1 on a failed criterion), render."""

from __future__ import annotations

import pytest

from negobs_gym.cli import main
from negobs_gym.eval.campaign import read_csv
from negobs_gym.spec import load_scenario, scenario_names, spec_from_toml

PAPER_SCENES = [
    n for n in scenario_names() if n.startswith(("paper_n_", "paper_t_")) and not n.endswith("_v0")
]

# no filter, a pit in the driving line, and a criterion that the reckless driver must fail
FAILING = """
name = "reckless_into_pit"
terminations = ["entered_negative_obstacle"]
[terrain.course]
length_m = 30.0
[[obstacles]]
kind = "ditch"
length_m = 1.0
width_m = 3.0
station_m = [8.0, 10.0]
[start]
speed_mps = 6.944444444444445
[episode]
time_limit_s = 4.0
[observation]
source = "oracle"
[run]
filter = false
[criteria]
entered_negative_obstacle = {entered}
"""


def _lines(capsys) -> list[str]:
    return [line for line in capsys.readouterr().out.splitlines() if line.strip()]


def test_driver_choices_are_the_runners_drivers():
    from negobs_gym.cli.scenario import DRIVER_CHOICES
    from negobs_gym.eval.scenario_runner import DRIVERS

    assert DRIVER_CHOICES == DRIVERS


def test_list_names_every_shipped_scenario(capsys):
    assert main(["scenario", "list"]) == 0
    listed = [line.split()[0] for line in _lines(capsys)]
    assert listed == list(scenario_names())
    assert len(PAPER_SCENES) == 10


def test_show_prints_toml_that_loads_back_equal(capsys):
    assert main(["scenario", "show", "paper_n_three_pits"]) == 0
    assert spec_from_toml(capsys.readouterr().out) == load_scenario("paper_n_three_pits")


def test_run_exits_non_zero_exactly_when_a_named_criterion_fails(tmp_path, capsys):
    for entered, code in (("false", 1), ("true", 0)):
        path = tmp_path / f"scene_{entered}.toml"
        path.write_text(FAILING.format(entered=entered))
        assert main(["scenario", "run", str(path), "--seeds", "2"]) == code
        lines = _lines(capsys)
        assert [line.split()[1] for line in lines] == ["seed=0", "seed=1"]
        assert all("entered=1" in line and "filter=off" in line for line in lines)
        assert all(line.endswith("FAIL entered_negative_obstacle") == (code == 1) for line in lines)


def test_run_video_writes_an_mp4_per_seed(tmp_path, capsys):
    pytest.importorskip("imageio_ffmpeg")
    path = tmp_path / "scene.toml"
    path.write_text(FAILING.format(entered="true"))
    videos = tmp_path / "videos"
    assert main(["scenario", "run", str(path), "--seeds", "2", "--video", str(videos)]) == 0
    assert len(_lines(capsys)) == 2
    names = sorted(p.name for p in videos.iterdir())
    assert names == ["reckless_into_pit_seed0.mp4", "reckless_into_pit_seed1.mp4"]
    assert all(b"ftyp" in (videos / n).read_bytes()[:16] for n in names)  # MP4 files


def test_run_out_writes_tables_that_the_written_spec_reproduces(tmp_path, capsys):
    """--out: the spec as run (driver and filter folded in) runs again to the same tables, in one
    process as in two (the two processes print a line per seed in seed order, from --seed on)."""
    path = tmp_path / "scene.toml"
    path.write_text(FAILING.format(entered="false"))
    first, again = tmp_path / "first", tmp_path / "again"
    seeds = ["--seed", "3", "--seeds", "2"]
    args = [*seeds, "--workers", "2", "--driver", "constant_speed", "--filter", "--out", str(first)]
    code = main(["scenario", "run", str(path), *args])
    lines = _lines(capsys)
    assert [line.split()[:2] for line in lines] == [
        ["reckless_into_pit", "seed=3"],
        ["reckless_into_pit", "seed=4"],
    ]
    ran = spec_from_toml((first / "scenario.toml").read_text())
    assert (ran.run.driver, ran.run.filter) == ("constant_speed", True)
    results = read_csv(first / "results.csv")
    assert [(r["seed"], r["driver"], r["filter"]) for r in results] == [
        ("3", "constant_speed", "filter"),
        ("4", "constant_speed", "filter"),
    ]
    assert [r["passed"] == "1" for r in results] == [line.endswith("PASS") for line in lines]
    assert code == (0 if all(r["passed"] == "1" for r in results) else 1)
    assert read_csv(first / "vetoes.csv")  # the filter vetoed: the tables compared below hold rows
    rerun = ["scenario", "run", str(first / "scenario.toml"), *seeds, "--out", str(again)]
    assert main(rerun) == code
    assert _lines(capsys) == lines
    for name in ("results.csv", "vetoes.csv", "paths.csv", "scenario.toml"):
        assert (again / name).read_bytes() == (first / name).read_bytes(), name


def test_run_several_specs_as_a_suite(tmp_path, capsys):
    """Several SPECs run one after the other, each checked before any episode; --out gives each
    its folder; exit 1 when any seed of any spec fails."""
    passing, failing = tmp_path / "a.toml", tmp_path / "b.toml"
    passing.write_text(FAILING.format(entered="true").replace('"reckless_into_pit"', '"scene_a"'))
    failing.write_text(FAILING.format(entered="false").replace('"reckless_into_pit"', '"scene_b"'))
    out = tmp_path / "suite"
    assert main(["scenario", "run", str(passing), str(failing), "--seeds", "2", "--out", str(out)]) == 1
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    assert [line.split()[:2] for line in lines] == [
        ["scene_a", "seed=0"],
        ["scene_a", "seed=1"],
        ["scene_b", "seed=0"],
        ["scene_b", "seed=1"],
    ]
    assert [line.endswith("PASS") for line in lines] == [True, True, False, False]
    assert "2 of 4 runs failed a criterion: scene_b seed=0, scene_b seed=1" in captured.err
    for name, passed in (("scene_a", "1"), ("scene_b", "0")):
        assert [r["passed"] for r in read_csv(out / name / "results.csv")] == [passed, passed]
        assert spec_from_toml((out / name / "scenario.toml").read_text()).name == name
    assert main(["scenario", "run", str(passing), str(passing), "--out", str(out)]) == 2
    assert "['scene_a'] named twice" in capsys.readouterr().err
    assert main(["scenario", "run", str(passing), "no_such_scene"]) == 2
    captured = capsys.readouterr()
    assert "unknown scenario" in captured.err and captured.out == ""  # no episode ran


def test_run_policy_drives_and_is_recorded_in_the_spec(tmp_path, capsys):
    """--policy: a trained policy drives; scenario.toml records it (run.policy), --driver takes the
    wheel back, and a policy that does not exist is refused before the first episode."""
    short = ["--set", "episode.time_limit_s=1"]
    out = tmp_path / "policy"
    run = ["scenario", "run", "offroad_nav_v1", *short, "--out", str(out)]
    assert main([*run, "--policy", "ppo_offroad_nav_v1"]) == 0
    assert "driver=ppo_offroad_nav_v1 " in _lines(capsys)[0]
    ran = spec_from_toml((out / "scenario.toml").read_text()).run
    assert (ran.policy, ran.policy_algo) == ("ppo_offroad_nav_v1", "PPO")
    assert read_csv(out / "results.csv")[0]["driver"] == "ppo_offroad_nav_v1"
    scripted = ["scenario", "run", str(out / "scenario.toml"), "--driver", "reckless", "--out", str(out)]
    assert main(scripted) == 0
    assert "driver=reckless " in _lines(capsys)[0]
    assert spec_from_toml((out / "scenario.toml").read_text()).run.policy == ""
    assert main([*run, "--policy", str(tmp_path / "no_model.zip")]) == 2
    assert "run.policy: no saved model at" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: one driver or the other
        main([*run, "--policy", "ppo_offroad_nav_v1", "--driver", "reckless"])
    assert "not allowed with argument" in capsys.readouterr().err


def test_run_policy_warns_when_the_scenario_lacks_its_fitted_settings(capsys):
    """A model fitted with --set settings (its record) on a scenario without them: a warning that
    names them; with them, none."""
    fitted = "reward.goal_approach=2.0"
    run = ["scenario", "run", "offroad_nav_v1", "--policy", "ppo_offroad_nav_v1_pem"]
    run += ["--set", "episode.time_limit_s=0.1"]
    assert main(run) == 0
    warning = "ppo_offroad_nav_v1_pem was fitted with --set " + " --set ".join(fitted.split())
    assert f"{warning}, which offroad_nav_v1 lacks" in capsys.readouterr().err
    assert main([*run, *(f"--set={s}" for s in fitted.split())]) == 0
    assert "was fitted with" not in capsys.readouterr().err


def test_set_changes_a_setting_of_show_and_run(tmp_path, capsys):
    setting = ["--set", "observation.tighten_pairs=false", "--set", "episode.time_limit_s=3.5"]
    assert main(["scenario", "show", "paper_n_three_pits", *setting]) == 0
    shown = spec_from_toml(capsys.readouterr().out)
    assert shown.observation.tighten_pairs is False and shown.episode.time_limit_s == 3.5
    # the criterion the reckless driver fails, flipped from the command line: the run passes
    path = tmp_path / "scene.toml"
    path.write_text(FAILING.format(entered="false"))
    assert main(["scenario", "run", str(path), "--set", "criteria.entered_negative_obstacle=true"]) == 0
    assert _lines(capsys)[0].endswith("PASS")
    assert main(["scenario", "show", "paper_n_three_pits", "--set", "observation.tighten_pairs=yes"]) == 2
    err = capsys.readouterr().err.strip()
    assert "observation.tighten_pairs: must be true or false" in err and "\n" not in err


def test_unknown_scenario_is_a_one_line_error(capsys):
    assert main(["scenario", "run", "no_such_scene"]) == 2
    assert "unknown scenario" in capsys.readouterr().err


def test_render_writes_a_png(tmp_path):
    out = tmp_path / "sub" / "scene.png"
    assert main(["scenario", "render", "paper_t_parked_motorbike", "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in out.parent.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.slow
@pytest.mark.parametrize("scene", PAPER_SCENES)
def test_run_each_paper_scene_prints_a_line_per_seed(scene, capsys):
    code = main(["scenario", "run", scene, "--seeds", "2"])
    lines = _lines(capsys)
    assert [line.split()[:2] for line in lines] == [[scene, "seed=0"], [scene, "seed=1"]]
    assert code == (0 if all(line.endswith("PASS") for line in lines) else 1)


# slow (end to end): stop_for_positive is checked by
# tests/safety/test_filter.py::test_positive_obstacles_are_ignored_unless_stop_for_positive
@pytest.mark.slow
def test_run_stop_for_positive_turns_the_filter_to_the_rock(tmp_path, capsys) -> None:
    """The rock scene with its filter.stop_for_positive off hits the rock; the flag turns it on."""
    import dataclasses

    from negobs_gym.spec import spec_to_toml

    spec = load_scenario("rock_on_track_25kmh")
    paper = dataclasses.replace(spec, filter=dataclasses.replace(spec.filter, stop_for_positive=False))
    path = tmp_path / "rock.toml"
    path.write_text(spec_to_toml(paper))
    assert main(["scenario", "run", str(path), "--stop-for-positive", "--draw", str(tmp_path / "drawn")]) == 0
    line = capsys.readouterr().out.strip()
    assert " collision=0 " in line and " false_vetoes=0 " in line and line.endswith("PASS")
    import matplotlib.image as mpimg

    image = mpimg.imread(tmp_path / "drawn" / f"{spec.name}_seed0.png")[..., :3]
    magenta = (image[..., 0] > 0.8) & (image[..., 1] < 0.3) & (image[..., 2] > 0.8)
    assert magenta.any()  # the vetoed steps before the rock
    capsys.readouterr()
    zoomed = ["--stop-for-positive", "--draw", str(tmp_path / "z"), "--zoom", "5"]
    assert main(["scenario", "run", str(path), *zoomed]) == 0
    close = mpimg.imread(tmp_path / "z" / f"{spec.name}_seed0.png")[..., :3]
    assert close.shape[:2] == (1000, 1000)  # the 10 m square around where the car stopped
    close_magenta = (close[..., 0] > 0.8) & (close[..., 1] < 0.3) & (close[..., 2] > 0.8)
    assert close_magenta.sum() > magenta.sum()  # the same marks, drawn larger
    assert main(["scenario", "run", str(path), "--zoom", "5"]) == 2
    assert "--zoom: needs --draw DIR" in capsys.readouterr().err
