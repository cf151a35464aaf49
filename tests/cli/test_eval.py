"""``negobs eval``: --help, TOML config, clean errors, and a saved SB3 model evaluated on seeds."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.cli import build_parser, main
from negobs_gym.cli.eval import braking_config, build_config, load_toml, with_overrides
from negobs_gym.errors import ConfigError
from negobs_gym.eval.campaign import read_csv
from negobs_gym.eval.detection_campaign import DetectionCampaignConfig
from negobs_gym.eval.stats import format_interval, rate_interval
from negobs_gym.spec import apply_overrides, load_scenario, spec_from_toml


@pytest.mark.parametrize("campaign", ["detection", "braking", "policy"])
def test_every_campaign_has_help(campaign: str, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["eval", campaign, "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert f"negobs eval {campaign}" in out
    assert all(
        opt in out for opt in ("--seeds", "--out", "--workers", "--ray", "--resume", "--rig", "--config")
    )


def test_toml_fields_and_command_line_precedence(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text('rig = "reduced"\nseeds = 3\n[detection]\nframes = 30\nspacing_m = [6.0, 9.0]\n')
    fields = load_toml(path, "detection")
    assert fields == {"rig": "reduced", "seeds": 3, "frames": 30, "spacing_m": (6.0, 9.0)}
    cfg = build_config(DetectionCampaignConfig, fields, {"seeds": 5, "frames": None})
    assert (cfg.seeds, cfg.frames, cfg.rig, cfg.spacing_m) == (5, 30, "reduced", (6.0, 9.0))
    with pytest.raises(ConfigError, match="unknown keys"):
        build_config(DetectionCampaignConfig, {"frame": 3}, {})


def test_bad_config_and_missing_ray_exit_2(tmp_path: Path, monkeypatch, capsys) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("frames = [\n")
    out = ["--out", str(tmp_path / "o")]
    assert main(["eval", "detection", "--config", str(bad), *out]) == 2
    assert "cannot read" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "ray", None)
    assert main(["eval", "detection", "--ray", *out]) == 2
    assert "negobs_gym[ray]" in capsys.readouterr().err


def test_braking_scene_options_are_set_paths_in_order(tmp_path: Path) -> None:
    """--rig, --tighten-pairs, --scan-every and --scan-far-from (and the TOML keys of the same
    names) are their --set paths: the file's, its overrides, the command's options, then --set."""
    config = tmp_path / "c.toml"
    config.write_text('rig = "reduced"\n[braking]\noverrides = ["observation.scan_every=2"]\nseeds = 2\n')
    argv = ["eval", "braking", "--config", str(config), "--rig", "native", "--no-tighten-pairs"]
    argv += ["--scan-every", "4", "--scan-far-from", "12", "--set", "observation.rig=roi"]
    cfg = braking_config(build_parser().parse_args(argv))
    assert cfg.seeds == 2 and cfg.overrides == (
        'observation.rig="reduced"',
        "observation.scan_every=2",
        'observation.rig="native"',
        "observation.tighten_pairs=false",
        "observation.scan_every=4",
        "observation.scan_far_from_m=12.0",
        "observation.rig=roi",
    )
    observation = apply_overrides(load_scenario("braking_campaign_ditch"), cfg.overrides).observation
    assert (observation.rig, observation.tighten_pairs, observation.scan_every) == ("roi", False, 4)
    assert observation.scan_far_from_m == 12.0
    assert braking_config(build_parser().parse_args(["eval", "braking"])).overrides == ()
    # the policy campaign's --source (and a TOML file's source) is observation.source
    paths = {"source": "observation.source"}
    toml, cli = with_overrides(paths, {"source": "oracle", "seeds": 2}, {"source": None})
    assert toml == {"seeds": 2} and cli == {"overrides": ('observation.source="oracle"',)}
    config.write_text("[braking]\ntighten_pair = false\n")  # a misspelt key is still refused
    with pytest.raises(ConfigError, match="unknown keys"):
        braking_config(build_parser().parse_args(["eval", "braking", "--config", str(config)]))


def test_braking_refuses_a_far_part_outside_the_grid_naming_it(tmp_path: Path, capsys) -> None:
    out = ["--out", str(tmp_path / "o"), "--seeds", "1"]
    assert main(["eval", "braking", "--scan-every", "3", "--scan-far-from", "40", *out]) == 2
    assert "scan_far_from_m" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# slow (end to end): a saved model evaluated through the CLI is also checked by
# tests/cli/test_train.py::test_train_saves_a_model_that_eval_policy_loads
@pytest.mark.slow
def test_policy_source_replaces_the_source_its_record_set(tmp_path: Path, monkeypatch, capsys) -> None:
    """A model trained with --source pem, evaluated with --source detector, runs on the detector
    grid: the command's source goes after the record's settings, as a --set does."""
    import gymnasium as gym
    from stable_baselines3 import PPO

    import negobs_gym  # noqa: F401  (registers the envs)
    from negobs_gym.drivers import zoo

    env = gym.make("negobs_gym/Braking-v0")
    path = tmp_path / "tiny.zip"
    PPO("MultiInputPolicy", env, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu").save(path)
    env.close()
    monkeypatch.setattr(
        zoo, "recorded_env", lambda model: ("negobs_gym/Braking-v0", ("observation.source=pem",))
    )
    out = tmp_path / "run"
    args = ["eval", "policy", str(path), "--seeds", "1", "--filter", "off", "--source", "oracle"]
    args += ["--set", "episode.time_limit_s=0.3", "--out", str(out), "--no-progress"]
    assert main(["-q", *args]) == 0
    assert "observation.source=oracle]" in capsys.readouterr().out.split()[0]
    assert spec_from_toml((out / "scenario.toml").read_text()).observation.source == "oracle"


def test_policy_evaluates_a_saved_model(tmp_path: Path, capsys) -> None:
    import gymnasium as gym
    from stable_baselines3 import PPO

    import negobs_gym  # registers the envs; its folder holds the shipped scenes

    env = gym.make("negobs_gym/Braking-v0")
    model = PPO("MultiInputPolicy", env, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=16)
    path = tmp_path / "tiny.zip"
    model.save(path)
    env.close()
    out = tmp_path / "policy"
    args = ["eval", "policy", str(path), "--seeds", "1", "--filter", "on", "--out", str(out), "--no-progress"]
    assert main(["-q", *args]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    assert line.startswith("negobs_gym/Braking-v0/filter success=") and " goal=0/1 " in line
    rows = (out / "policy.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[0].startswith("episode,env,filter,seed,success")
    assert rows[1].split(",")[3] == "1000000"  # unseen seeds by default
    fields = dict(item.split("=", 1) for item in line.split()[1:])
    episode = dict(zip(rows[0].split(","), rows[1].split(","), strict=True))
    km = float(episode["distance_m"]) / 1000
    per_km = int(episode["vetoes"]) / km if km else 0
    assert float(fields["vetoes_per_km"]) == pytest.approx(per_km, abs=0.051)
    assert fields["false_vetoes"] == episode["false_vetoes"]
    assert fields["veto_events"] == episode["veto_events"]  # the onset vetoes of vetoes.csv below
    assert int(episode["false_vetoes"]) <= int(episode["vetoes"])
    assert fields["missed_vetoes"] == episode["missed_vetoes"]
    # the rates' 95 % Wilson intervals: one episode, no goal
    assert fields["goal_interval"] == format_interval(rate_interval(0, 1)) == "0.00-0.79"
    success = int(episode["success"])
    assert fields["success_interval"] == format_interval(rate_interval(success, 1))
    error = float(episode["max_veto_error_m"])  # NaN: no veto with a true hazard
    assert fields["veto_error_m"] == ("-" if math.isnan(error) else f"{error:+.2f}")
    # each veto judged in vetoes.csv: as many rows as the episode's vetoes and missed vetoes
    vetoes = read_csv(out / "vetoes.csv")
    assert sum(v["kind"] == "veto" for v in vetoes) == int(episode["vetoes"])
    assert sum(v["kind"] == "missed" for v in vetoes) == int(episode["missed_vetoes"])
    assert sum(v["onset"] == "1" for v in vetoes) == int(episode["veto_events"])
    judged = [float(v["error_m"]) for v in vetoes if v["kind"] == "veto" and v["error_m"] != "nan"]
    median = f"{float(np.median(judged)):+.2f}" if judged else "-"
    assert fields["median_veto_error_m"] == median
    onsets = [float(v["error_m"]) for v in vetoes if v["onset"] == "1" and v["error_m"] != "nan"]
    assert fields["median_onset_veto_error_m"] == (f"{float(np.median(onsets)):+.2f}" if onsets else "-")
    # another first seed, on the oracle grid
    oracle = ["eval", "policy", str(path), "--seeds", "2", "--first-seed", "5", "--filter", "off", "--source"]
    assert main(["-q", *oracle, "oracle", "--out", str(tmp_path / "oracle"), "--no-progress"]) == 0
    label = "negobs_gym/Braking-v0[observation.source=oracle]"  # the id and the source it ran on
    assert capsys.readouterr().out.startswith(f"{label}/nofilter success=")
    seeds = [r.split(",")[3] for r in (tmp_path / "oracle" / "policy.csv").read_text().splitlines()[1:]]
    assert seeds == ["5", "6"]
    # a scenario TOML file as the env: Braking-v0's scene with the structure channel, its own grid
    scene = tmp_path / "braking_structure.toml"
    shipped = Path(negobs_gym.__file__).parent / "spec" / "scenes" / "braking_v0.toml"
    scene.write_text(shipped.read_text() + '\n[observation]\npositive_detector = "structure"\n')
    toml_run = ["eval", "policy", str(path), "--env", str(scene), "--seeds", "1", "--filter", "both"]
    toml_run += ["--set", "episode.time_limit_s=1"]  # what is checked here needs no whole episode
    assert (
        main(["-q", *toml_run, "--stop-for-positive", "--out", str(tmp_path / "toml"), "--no-progress"]) == 0
    )
    lines = capsys.readouterr().out.splitlines()
    label = f"{scene}[episode.time_limit_s=1]"
    assert [line.split()[0] for line in lines] == [f"{label}/nofilter", f"{label}/filter_positive"]
    labels = [r.split(",")[2] for r in (tmp_path / "toml" / "policy.csv").read_text().splitlines()[1:]]
    assert sorted(labels) == ["filter_positive", "nofilter"]
    # the scene's own filter.stop_for_positive, set with --set, is the filter's without the flag
    scene_says = ["eval", "policy", str(path), "--seeds", "1", "--filter", "on"]
    scene_says += ["--set", "episode.time_limit_s=1", "--set", "filter.stop_for_positive=true"]
    assert main(["-q", *scene_says, "--out", str(tmp_path / "scene_says"), "--no-progress"]) == 0
    assert capsys.readouterr().out.split()[0].endswith("/filter_positive")
    told = (tmp_path / "scene_says" / "policy.csv").read_text().splitlines()[1:]
    assert [r.split(",")[2] for r in told] == ["filter_positive"]
    assert main(["eval", "policy", str(tmp_path / "none.zip"), "--out", str(out)]) == 2
    # --set: the env's scenario with one setting changed, recorded as OUT/scenario.toml
    short = ["eval", "policy", str(path), "--seeds", "1", "--filter", "off"]
    short += ["--set", "episode.time_limit_s=0.5"]
    assert main(["-q", *short, "--out", str(tmp_path / "set"), "--no-progress"]) == 0
    written = tmp_path / "set" / "scenario.toml"
    label = "negobs_gym/Braking-v0[episode.time_limit_s=0.5]"  # the id and its settings
    assert capsys.readouterr().out.startswith(f"{label}/nofilter success=")
    assert spec_from_toml(written.read_text()).episode.time_limit_s == 0.5
    # a shipped policy without --env: its record's env and settings (the goal-approach reward of
    # this PEM-trained policy), then the command's --set, which replaces the record's assignment
    # to that key
    shipped = ["eval", "policy", "ppo_offroad_nav_v1_pem", "--seeds", "1", "--filter", "off"]
    shipped += ["--set", "reward.goal_approach=0.5", "--set", "episode.time_limit_s=0.3"]
    shipped += ["--out", str(tmp_path / "shipped"), "--no-progress"]
    assert main(["-q", *shipped]) == 0
    label = "negobs_gym/OffroadNav-v1[reward.goal_approach=0.5,episode.time_limit_s=0.3]"
    line = capsys.readouterr().out
    assert line.startswith(f"{label}/nofilter success=") and " goal=0/1 " in line
    spec = spec_from_toml((tmp_path / "shipped" / "scenario.toml").read_text())
    assert spec.reward.goal_approach == 0.5 and spec.episode.time_limit_s == 0.3
    assert spec.observation.source == "detector"  # judged on the default grid, not the PEM it trained on
    # the episode's record keeps the shipped policy's name, not this install's path to it, so the
    # folder replays wherever the package is installed
    (part,) = (tmp_path / "shipped" / "parts").glob("*.json")
    assert json.loads(part.read_text())["args"]["model_path"] == "ppo_offroad_nav_v1_pem"
    (row,) = (tmp_path / "set" / "policy.csv").read_text().splitlines()[1:]
    assert int(dict(zip(rows[0].split(","), row.split(","), strict=True))["steps"]) <= 5
    # the same model as a driver of the braking campaign, filter on only (set from a TOML file)
    config = tmp_path / "braking.toml"
    config.write_text("[braking]\nfilters = [true]\n")
    braking = [
        "eval",
        "braking",
        "--model",
        str(path),
        "--drivers",
        "sb3",
        "--scenarios",
        "ditch",
        "--seeds",
        "1",
    ]
    braking += ["--no-tighten-pairs"]  # paper N's fusion history instead of the envs' default
    assert main(["-q", *braking, "--config", str(config), "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    assert line.startswith("ditch/sb3/filter stopped_before=")
    (part,) = (tmp_path / "b" / "parts").glob("*.json")
    assert json.loads(part.read_text())["args"]["overrides"] == ["observation.tighten_pairs=false"]
