"""Shipped trained policies: their records, their loading, and names in place of model paths."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from negobs_gym.drivers.zoo import (
    baseline_names,
    baseline_record,
    fitted_on_record,
    recorded_env,
    resolve_model,
)
from negobs_gym.errors import ConfigError


def test_a_path_resolves_to_itself_and_an_unknown_name_is_refused(tmp_path: Path) -> None:
    model = tmp_path / "m.zip"
    model.write_bytes(b"not read here")
    assert resolve_model(str(model)) == str(model)
    assert resolve_model(str(tmp_path / "m")) == str(tmp_path / "m")  # SB3 adds .zip itself
    with pytest.raises(ConfigError, match="no shipped baseline"):
        resolve_model("no_such_policy")
    with pytest.raises(ConfigError, match="no shipped baseline"):
        baseline_record("no_such_policy")


@pytest.mark.parametrize("name", baseline_names())
def test_each_shipped_baseline_has_its_record_and_runs_on_its_env(name: str) -> None:
    from stable_baselines3 import PPO

    import negobs_gym  # noqa: F401 - registers the envs
    from negobs_gym.envs import make_env
    from negobs_gym.policies.observation import match_observation

    record = baseline_record(name)
    for key in ("command", "seed", "steps", "wall_s", "env", "evaluation"):
        assert key in record, f"{name}.json lacks {key!r}"
    assert record["command"].startswith("negobs train ")
    settings = record.get("set", [])  # the --set its commands carry, or its recipe's
    assert "--recipe " in record["command"] or all(f"--set {s}" in record["command"] for s in settings)
    model = PPO.load(resolve_model(name), device="cpu")
    assert recorded_env(name) == (record["env"], tuple(settings))  # eval policy's default --env
    assert recorded_env(resolve_model(name)) == recorded_env(name)  # named by its shipped file
    env = make_env(record["env"], settings)  # id or scenario
    obs, _ = env.reset(seed=1_000_000)
    action, _ = model.predict(match_observation(obs, model.observation_space), deterministic=True)
    assert env.action_space.contains(action.astype(env.action_space.dtype))
    env.close()


@pytest.mark.parametrize("name", baseline_names())
def test_each_shipped_baselines_training_command_still_parses_to_its_env_and_set(name: str) -> None:
    """The records' commands use --source and --filter: now short names of --set assignments."""
    import shlex

    from negobs_gym.cli import build_parser
    from negobs_gym.cli.train import config_from_args
    from negobs_gym.policies.recipes import load_recipe

    record = baseline_record(name)
    words = shlex.split(record["command"])
    config = config_from_args(build_parser().parse_args(words[1:]))
    assert config.env == record["env"] and set(record.get("set", ())) <= set(config.overrides)
    source = words[words.index("--source") + 1] if "--source" in words else None
    if source is not None:
        assert f"observation.source={source}" in config.overrides
    recipe = load_recipe(words[words.index("--recipe") + 1]) if "--recipe" in words else None
    filtered = "--filter" in words or (recipe is not None and "run.filter=true" in recipe.train.overrides)
    assert ("run.filter=true" in config.overrides) == filtered
    if recipe is not None:  # the command is the recipe's run with its output options
        assert dataclasses.replace(config, progress=True) == dataclasses.replace(recipe.train, progress=True)


def test_at_least_one_baseline_is_shipped() -> None:
    assert baseline_names(), "no trained policy under negobs_gym/drivers/trained"


def test_a_training_folder_records_the_env_of_its_models(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    for model in ("model.zip", "warm_start.zip", "checkpoints/model_64.zip"):
        (run / model).write_bytes(b"zip")
    loose = tmp_path / "loose.zip"
    loose.write_bytes(b"zip")
    (run / "train.json").write_text(json.dumps({"config": {"env": "negobs_gym/OffroadTrack-v0"}}))
    for model in ("model.zip", "warm_start.zip", "checkpoints/model_64.zip", "model"):
        assert recorded_env(str(run / model)) == ("negobs_gym/OffroadTrack-v0", ())
    assert recorded_env(str(loose)) is None and recorded_env(str(tmp_path / "none.zip")) is None
    # a --set run records OUT/scenario.toml relative to where it ran: found beside train.json
    (run / "train.json").write_text(json.dumps({"config": {"env": "elsewhere/run/scenario.toml"}}))
    (run / "scenario.toml").write_text("name = 'x'\n")
    assert recorded_env(str(run / "model.zip")) == (str(run / "scenario.toml"), ())


def test_the_record_inside_a_model_zip_comes_first_and_a_zip_without_one_falls_back(tmp_path: Path) -> None:
    import zipfile

    from negobs_gym.drivers.zoo import FITTED_ON, fitted_on_record

    run = tmp_path / "run"
    run.mkdir()
    (run / "train.json").write_text(json.dumps({"config": {"env": str(run / "scenario.toml")}}))
    (run / "scenario.toml").write_text("name = 'x'\n")

    def model(name: str, data: bytes) -> str:
        with zipfile.ZipFile(run / name, "w") as archive:  # SB3's layout: JSON attributes in "data"
            archive.writestr("data", data)
        return str(run / name)

    record = fitted_on_record("negobs_gym/OffroadTrack-v0", ["observation.tighten_pairs=false"])
    recorded = model("recorded.zip", json.dumps({"gamma": 0.99, FITTED_ON: record}).encode())
    assert recorded_env(recorded) == ("negobs_gym/OffroadTrack-v0", ("observation.tighten_pairs=false",))
    for name, data in {
        "older.zip": json.dumps({"gamma": 0.99}).encode(),  # saved before the record existed
        "garbled.zip": b"{not json",
        "odd.zip": json.dumps({FITTED_ON: {"env": 3}}).encode(),
        "odd_set.zip": json.dumps({FITTED_ON: {"env": "negobs_gym/OffroadTrack-v0", "set": "a=1"}}).encode(),
    }.items():
        assert recorded_env(model(name, data)) == (str(run / "scenario.toml"), ()), name


def test_a_scenario_file_is_recorded_by_a_path_that_holds_from_any_directory(
    tmp_path: Path, monkeypatch
) -> None:
    (tmp_path / "mine.toml").write_text("base = 'negobs_gym/Braking-v1'\n")
    monkeypatch.chdir(tmp_path)
    record = fitted_on_record("mine.toml", ["episode.time_limit_s=2.0"])
    monkeypatch.chdir(tmp_path.parent)
    assert Path(record["env"]).is_file() and Path(record["env"]).samefile(tmp_path / "mine.toml")
    assert record["set"] == ["episode.time_limit_s=2.0"]
    assert fitted_on_record("negobs_gym/Braking-v1") == {"env": "negobs_gym/Braking-v1", "set": []}
