"""``negobs train``: a short oracle-grid PPO run whose model ``negobs eval policy`` loads; bad arguments;
the options table (each flag once; the scenario ones are --set assignments)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from stable_baselines3 import PPO

from negobs_gym.cli import main
from negobs_gym.policies.callbacks import EVAL_COLUMNS
from negobs_gym.policies.config import WarmStartConfig
from negobs_gym.policies.modes import SteeringModesPolicy
from negobs_gym.policies.route_offset import RouteOffsetPolicy

ENV = "negobs_gym/Braking-v1"
SHORT = ["--source", "oracle", "--n-steps", "64", "--eval-episodes", "1", "--no-progress"]
#: OffroadTrack-v0's shortest course (its obstacles 20-45 m along it): each reset builds less terrain
SHORT_COURSE = ["--set", "terrain.params.length_m=60"]


def test_train_saves_a_model_that_eval_policy_loads(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    args = ["train", "--env", ENV, "--steps", "200", "--eval-every", "128", "--checkpoint-every", "100"]
    assert main(["-q", *args, *SHORT, "--out", str(out)]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    fields = dict(item.split("=", 1) for item in line.split())
    assert fields["model"] == str(out / "model.zip") and int(fields["steps"]) == 256  # 4 rollouts of 64
    assert float(fields["steps_per_s"]) > 0
    with (out / "eval.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == EVAL_COLUMNS
    assert [int(r["step"]) for r in rows] == [128, 256]  # every 128 steps; the last one is the end
    assert all(int(r["episodes"]) == 1 and float(r["mean_progress_m"]) > 0 for r in rows)
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == [
        "model_100.zip",
        "model_200.zip",
        "model_256.zip",
    ]
    header = (out / "logs" / "0" / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"time/total_timesteps", "train/loss", "eval/goal", "eval/entries"} <= set(header)
    record = json.loads((out / "train.json").read_text())
    assert record["steps"] == 256 and record["config"]["overrides"] == ["observation.source=oracle"]
    assert record["config"]["extractor"]["conv_channels"] == [16, 32, 32]

    assert main(["-q", *args, *SHORT, "--out", str(out)]) == 2  # a new run would mix with this one
    assert "use --resume or another --out" in capsys.readouterr().err

    # the default (detector-grid) env of the id, behind the filter: the flat-grid model runs on it
    evaluation = ["eval", "policy", str(out / "model.zip"), "--env", ENV, "--seeds", "1", "--filter", "on"]
    assert main(["-q", *evaluation, "--out", str(tmp_path / "eval"), "--no-progress"]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    assert line.startswith(f"{ENV}/filter success=") and "/1 " in line
    assert 0.0 <= float(line.rsplit("off_track_share=", 1)[1]) <= 1.0
    # without --env: the env the model records (Braking-v1 on the oracle grid it was fitted on),
    # not eval policy's Braking-v0
    evaluation = ["eval", "policy", str(out / "model.zip"), "--seeds", "1", "--filter", "off"]
    assert main(["-q", *evaluation, "--out", str(tmp_path / "eval2"), "--no-progress"]) == 0
    assert capsys.readouterr().out.startswith(f"{ENV}[observation.source=oracle]/nofilter success=")


# slow (end to end): the CLI's DAgger warm start; DAgger itself is checked by
# tests/policies/test_pretrain.py
@pytest.mark.slow
def test_track_planner_warm_start_with_dagger_is_recorded_and_evaluated(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    args = ["train", "--env", "negobs_gym/OffroadTrack-v0", "--steps", "32", "--warm-start-steps", "40"]
    args += ["--warm-start-driver", "track_planner", "--dagger-rounds", "1", "--checkpoint-every", "0"]
    args += ["--critic-warmup-steps", "32", "--target-kl", "0.02", "--planner-sight-m", "14"]
    args += ["--mirror-demonstrations", "--planner-horizon-m", "30", "--warm-start-workers", "2"]
    args += [*SHORT, "--n-steps", "32", "--batch-size", "32", *SHORT_COURSE]  # one 32-step minibatch
    assert main(["-q", *args, "--out", str(out)]) == 0
    capsys.readouterr()
    record = json.loads((out / "train.json").read_text())
    assert record["config"]["critic_warmup_steps"] == 32 and record["config"]["target_kl"] == 0.02
    warm = record["warm_start"]
    assert warm["driver"] == "track_planner" and warm["dagger_rounds"] == 1
    assert warm["planner_sight_m"] == 14.0 and record["config"]["warm_start"]["planner_sight_m"] == 14.0
    assert warm["demonstration_steps"] == 80 and warm["episodes"] >= 2  # the clone drove a new course
    assert warm["mirror"] and record["config"]["warm_start"]["mirror"]
    assert warm["workers"] == 2  # the clone drove its DAgger round in other processes
    assert warm["planner_horizon_m"] == 30.0 == record["config"]["warm_start"]["planner_horizon_m"]
    assert warm["held_out_losses"] == [] and warm["best_epoch"] == WarmStartConfig().epochs - 1
    with (out / "eval.csv").open() as fh:
        steps = [int(r["step"]) for r in csv.DictReader(fh)]
    assert steps == [0, 32]  # the cloned policy, then after PPO
    assert (out / "warm_start.zip").is_file() and (out / "model.zip").is_file()
    # every labelled step is kept, and a new run can fit them again without collecting any
    saved = out / "demonstrations.npz"
    refit = tmp_path / "refit"
    args = ["train", "--env", "negobs_gym/OffroadTrack-v0", "--steps", "32", "--demonstrations", str(saved)]
    args += ["--strong-steer-repeats", "3", "--strong-steer", "0.2", "--steering-bins", "0"]
    args += ["--hold-out-every", "2", *SHORT, "--n-steps", "32", "--batch-size", "32", *SHORT_COURSE]
    assert main(["-q", *args, "--out", str(refit)]) == 0
    capsys.readouterr()
    record = json.loads((refit / "train.json").read_text())
    assert record["config"]["head"]["modes"] == 2 and record["config"]["head"]["bin_edges"] == [0.0]
    for name in ("warm_start.zip", "model.zip"):  # the clone, then after PPO's update through the head
        assert isinstance(PPO.load(refit / name, device="cpu").policy, SteeringModesPolicy)
    again = record["warm_start"]
    assert again["demonstrations"] == str(saved) and again["steps"] == 0
    assert again["strong_steer_repeats"] == 3 and again["strong_steer"] == 0.2
    assert again["demonstration_steps"] == 80 and again["episodes"] == warm["episodes"]
    assert len(again["held_out_losses"]) == WarmStartConfig().epochs  # the clone's episode, scored
    # the same steps fitted by a route-offset head: the clone and the PPO model keep it
    offset = tmp_path / "offset"
    args = ["train", "--env", "negobs_gym/OffroadTrack-v0", "--steps", "32", "--demonstrations", str(saved)]
    args += ["--route-offset-m", "2.5", *SHORT, "--n-steps", "32", "--batch-size", "32", *SHORT_COURSE]
    assert main(["-q", *args, "--out", str(offset)]) == 0
    capsys.readouterr()
    assert json.loads((offset / "train.json").read_text())["config"]["head"]["route_offset_m"] == 2.5
    for name in ("warm_start.zip", "model.zip"):
        policy = PPO.load(offset / name, device="cpu").policy
        assert isinstance(policy, RouteOffsetPolicy) and policy.head.route_offset_m == 2.5


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--steps", "0"], "--steps: must be >= 1, got 0"),
        (["--algo", "dqn"], "invalid choice: 'DQN'"),
        (["--source", "lidar"], "invalid choice: 'lidar'"),
        (["--envs", "0"], "--envs: must be >= 1"),
        (["--vec-env", "async"], "invalid choice: 'async'"),
        (["--warm-start-driver", "reckless"], "invalid choice: 'reckless'"),
        (["--strong-steer-repeats", "0"], "--strong-steer-repeats: must be >= 1"),
        (["--steering-modes", "0"], "--steering-modes: must be >= 1"),
        (["--steering-bins", "x"], "--steering-bins: invalid float value: 'x'"),
        (["--route-offset-m", "x"], "--route-offset-m: invalid float value: 'x'"),
    ],
)
def test_bad_arguments_exit_2_with_the_reason(args: list[str], message: str, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["train", *args])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_unknown_env_and_resume_without_checkpoint_exit_2(tmp_path: Path, capsys) -> None:
    assert main(["train", "--env", "negobs_gym/Nope-v0", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "unknown env 'negobs_gym/Nope-v0'" in err and "negobs_gym/OffroadNav-v0" in err
    assert main(["train", "--env", ENV, *SHORT, "--resume", "--out", str(tmp_path)]) == 2
    assert "no checkpoint" in capsys.readouterr().err
    assert main(["train", "--env", ENV, "--algo", "sac", "--critic-warmup-steps", "10"]) == 2
    assert "critic_warmup_steps" in capsys.readouterr().err
    assert main(["train", "--env", ENV, "--stop-for-positive"]) == 2  # without --filter
    assert "filter.stop_for_positive: needs the filter" in capsys.readouterr().err
    assert main(["train", "--env", ENV, "--strong-steer", "nan"]) == 2
    assert "strong_steer: must be finite and >= 0, got nan" in capsys.readouterr().err
    assert main(["train", "--env", ENV, "--algo", "sac", "--steering-modes", "2"]) == 2
    assert (
        "head: steering candidates and route offsets replace a Gaussian policy's mean: PPO only"
        in capsys.readouterr().err
    )
    assert main(["train", "--env", ENV, "--route-offset-m", "3", "--steering-modes", "2"]) == 2
    assert "route_offset_m: steers by one offset: leave modes at 1 with it" in capsys.readouterr().err
    assert main(["train", "--env", ENV, "--steering-modes", "3", "--steering-bins", "0"]) == 2
    assert "bin_edges: needs one edge between each two of the 3 candidates" in capsys.readouterr().err


def test_set_trains_on_the_changed_scenario_and_a_resume_keeps_it(tmp_path: Path, capsys) -> None:
    from negobs_gym.spec import spec_from_toml

    out = tmp_path / "run"
    args = ["train", "--env", ENV, "--steps", "64", "--eval-every", "0", *SHORT, "--out", str(out)]
    assert main(["-q", *args, "--set", "episode.time_limit_s=2.0"]) == 0
    capsys.readouterr()
    scene = out / "scenario.toml"  # what trained, every setting applied
    assert spec_from_toml(scene.read_text()).episode.time_limit_s == 2.0
    record = json.loads((out / "train.json").read_text())
    assert record["config"]["env"] == ENV
    assert record["config"]["overrides"] == ["observation.source=oracle", "episode.time_limit_s=2.0"]
    with (out / "eval.csv").open() as fh:
        (row,) = list(csv.DictReader(fh))
    assert float(row["mean_progress_m"]) < 2.0 * 25 / 3.6 + 1.0  # 2 s at most, from 25 km/h
    # a resume with other settings would go on with another scenario: refused, the file kept
    assert main(["-q", *args, "--resume", "--steps", "128", "--set", "episode.time_limit_s=3.0"]) == 2
    assert "episode.time_limit_s: 2.0 there, 3.0 now" in capsys.readouterr().err
    assert spec_from_toml(scene.read_text()).episode.time_limit_s == 2.0
    # the same scenario spelt with --set instead of --source resumes
    same = [a for a in args if a not in ("--source", "oracle")] + ["--set", "observation.source=oracle"]
    assert main(["-q", *same, "--resume", "--steps", "128", "--set", "episode.time_limit_s=2.0"]) == 0
    assert "steps=128" in capsys.readouterr().out


def test_a_model_moved_out_of_its_run_keeps_the_env_and_set_it_was_fitted_on(tmp_path: Path, capsys) -> None:
    import zipfile

    from negobs_gym.drivers.zoo import FITTED_ON, recorded_env

    out = tmp_path / "run"
    args = ["train", "--env", ENV, "--steps", "64", "--eval-every", "0", *SHORT, "--out", str(out)]
    assert main(["-q", *args, "--set", "episode.time_limit_s=2.0"]) == 0
    capsys.readouterr()
    moved = tmp_path / "elsewhere" / "policy.zip"
    moved.parent.mkdir()
    (out / "model.zip").rename(moved)
    fitted = ("observation.source=oracle", "episode.time_limit_s=2.0")
    assert recorded_env(str(moved)) == (ENV, fitted)  # no train.json beside it
    evaluation = ["eval", "policy", str(moved), "--seeds", "1", "--filter", "off", "--no-progress"]
    assert main(["-q", *evaluation, "--out", str(tmp_path / "eval")]) == 0
    line = capsys.readouterr().out
    assert line.startswith(f"{ENV}[{','.join(fitted)}]/nofilter success=")
    assert float(line.split("mean_progress_m=", 1)[1].split()[0]) < 2.0 * 25 / 3.6 + 1.0  # its 2 s limit

    # the same model without the record: evaluated on eval policy's default env, with a warning
    bare = tmp_path / "elsewhere" / "bare.zip"
    with zipfile.ZipFile(moved) as source, zipfile.ZipFile(bare, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "data":
                stripped = {k: v for k, v in json.loads(data).items() if k != FITTED_ON}
                data = json.dumps(stripped).encode()
            target.writestr(item, data)
    assert recorded_env(str(bare)) is None
    evaluation = ["eval", "policy", str(bare), "--seeds", "1", "--filter", "off", "--no-progress"]
    assert main(["-q", *evaluation, "--source", "oracle", "--out", str(tmp_path / "eval_bare")]) == 0
    printed = capsys.readouterr()
    assert printed.out.startswith("negobs_gym/Braking-v0[observation.source=oracle]/nofilter success=")
    assert "has no record of the env it was fitted on: evaluating on negobs_gym/Braking-v0" in printed.err


def test_action_std_sets_the_warm_start_or_the_init_model() -> None:
    from negobs_gym.cli import build_parser
    from negobs_gym.cli.train import config_from_args

    def config(*args: str):
        return config_from_args(build_parser().parse_args(["train", *args]))

    assert config().warm_start.action_std == 0.3 and config().init_action_std == 0.0
    assert config("--action-std", "0.2").warm_start.action_std == 0.2
    assert config("--action-std", "0.2").init_action_std == 0.0  # no model to set
    assert config("--init", "m.zip").init_action_std == 0.0  # keeps the model's
    assert config("--init", "m.zip", "--action-std", "0.1").init_action_std == 0.1


def test_a_hold_out_is_parsed_and_needs_episodes_to_hold_out(tmp_path: Path, capsys) -> None:
    from negobs_gym.cli import build_parser
    from negobs_gym.cli.train import config_from_args

    parsed = config_from_args(build_parser().parse_args(["train", "--hold-out-every", "5"]))
    assert parsed.warm_start.hold_out_every == 5 and not parsed.warm_start.mirror
    assert main(["train", "--hold-out-every", "1", "--out", str(tmp_path)]) == 2
    assert "hold_out_every: must be 0 (no hold-out) or an int >= 2" in capsys.readouterr().err
    # 20 demonstration steps are one episode: nothing to hold out, said in one line before training
    args = [
        "train",
        "--env",
        "negobs_gym/OffroadTrack-v0",
        "--warm-start-steps",
        "20",
        "--hold-out-every",
        "2",
    ]
    assert main([*args, *SHORT, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "none held out among the 1 episodes collected: collect more episodes" in err


def test_each_option_is_one_row_and_the_scenario_ones_are_set_assignments(capsys) -> None:
    import dataclasses

    from negobs_gym.cli import build_parser
    from negobs_gym.cli.train import OPTIONS, SET, config_from_args, default_of
    from negobs_gym.policies.config import TrainConfig
    from negobs_gym.spec import load_scenario

    flags = [o.flag for o in OPTIONS]
    assert len(flags) == len(set(flags))
    table = load_scenario("braking_v1").to_dict()
    for option in OPTIONS:  # every target is a TrainConfig setting or a scenario's --set path
        if option.sets_scenario:
            node = table
            for key in option.target.removeprefix(SET).split("."):
                node = node[key]  # a KeyError: no such --set path
        else:
            default_of(option.target)

    def config(*args: str) -> TrainConfig:
        return config_from_args(build_parser().parse_args(["train", *args]))

    assert config() == TrainConfig()  # no option given: the config's defaults, the scenario's own settings
    short = config("--source", "oracle", "--filter", "--stop-for-positive", "--set", "episode.time_limit_s=3")
    spelt = [
        "observation.source=oracle",
        "run.filter=true",
        "filter.stop_for_positive=true",
        "episode.time_limit_s=3",
    ]
    assert short.overrides == tuple(spelt)
    assert config(*(a for s in spelt for a in ("--set", s))) == short
    state = config("--source", "state")
    assert state.overrides == ("observation.source=oracle",) and not state.grid_input
    # each value option lands on its path
    values = {
        "--steps": ("7", 7),
        "--seed": ("3", 3),
        "--learning-rate": ("0.01", 0.01),
        "--warm-start-steps": ("40", 40),
        "--clone-weight-decay": ("0.5", 0.5),
        "--warm-start-driver": ("track_planner", "track_planner"),
        "--algo": ("sac", "SAC"),
        "--init": ("m.zip", "m.zip"),
        "--demonstrations": ("d.npz", "d.npz"),
    }
    by_flag = {o.flag: o for o in OPTIONS}
    for flag, (text, value) in values.items():
        assert default_of(by_flag[flag].target, config(flag, text)) == value, flag
    assert not config("--no-progress").progress and config("--mirror-demonstrations").warm_start.mirror
    assert dataclasses.asdict(config("--steering-bins", "-0.3", "0.3").head)["modes"] == 3

    with pytest.raises(SystemExit):
        build_parser().parse_args(["train", "--help"])
    shown = " ".join(capsys.readouterr().out.split())
    assert all(flag in shown for flag in flags)
    assert "= --set run.filter=true" in shown and "= --set observation.source=SOURCE" in shown
    assert "(default: negobs_gym/OffroadNav-v0)" in shown and "(default: 100000)" in shown
