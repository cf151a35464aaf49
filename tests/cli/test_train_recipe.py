"""``negobs train --recipe``: the recipe's run, the options given beside it replacing its
settings (also when they give a default's value), a short recipe run end to end; ``--ray``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import negobs_gym
from negobs_gym.cli import build_parser, main
from negobs_gym.cli.train import config_from_args, out_dir
from negobs_gym.policies.config import TrainConfig
from negobs_gym.policies.recipes import load_recipe

RECIPE = """
[recipe]
description = "a 64-step oracle run with a 40-step clone, for tests"
policy_file = "warm_start.zip"

[train]
env = "negobs_gym/Braking-v1"
overrides = ["observation.source=oracle", "episode.time_limit_s=2.0"]
steps = 64
n_steps = 32
batch_size = 32
seed = 3
eval_every = 0
eval_episodes = 1
checkpoint_every = 0
progress = false

[train.warm_start]
steps = 40
epochs = 2

[evaluation]
first_seed = 2000000
seeds = 3
filter = "off"
"""


def _config(*args: str) -> TrainConfig:
    return config_from_args(build_parser().parse_args(["train", *args]))


def test_a_recipe_is_its_run_and_the_options_beside_it_replace_its_settings(tmp_path: Path) -> None:
    recipe = load_recipe("bc_offroad_nav_v2_detector")
    assert _config("--recipe", "bc_offroad_nav_v2_detector") == recipe.train
    changed = _config(
        "--recipe", "bc_offroad_nav_v2_detector", "--warm-start-steps", "2000", "--seed", "0", "--no-progress"
    )
    # --seed 0 is TrainConfig's default, and given, it still replaces the recipe's 1
    assert (changed.warm_start.steps, changed.seed, changed.progress) == (2000, 0, False)
    assert changed.warm_start.driver == "track_planner" and changed.warm_start.mirror  # the recipe's
    assert changed.steps == 64 and changed.overrides == recipe.train.overrides
    # --source and --set come after the recipe's overrides: the last assignment to a path wins
    pem = _config(
        "--recipe", "bc_offroad_nav_v2_detector", "--source", "pem", "--set", "episode.time_limit_s=5"
    )
    assert pem.overrides == (*recipe.train.overrides, "observation.source=pem", "episode.time_limit_s=5")
    state = _config("--recipe", "bc_offroad_nav_v2_detector", "--source", "state")
    assert not state.grid_input
    # --action-std with a recipe that starts from a trained model sets that model's std
    fine_tune = tmp_path / "fine_tune.toml"
    fine_tune.write_text('[train]\nenv = "negobs_gym/OffroadNav-v1"\ninit_model = "ppo_offroad_nav_v1"\n')
    assert _config("--recipe", str(fine_tune), "--action-std", "0.2").init_action_std == 0.2
    # without a recipe nothing changed: the defaults
    assert _config() == TrainConfig()


def test_ray_puts_the_envs_on_ray_actors(tmp_path: Path) -> None:
    assert _config("--ray").vec_env == "ray" and _config("--ray").ray_address == ""
    remote = _config("--ray", "ray://head:10001", "--envs", "4")
    assert (remote.vec_env, remote.ray_address, remote.envs) == ("ray", "ray://head:10001", 4)
    assert _config("--recipe", "ppo_offroad_nav_v1", "--ray").vec_env == "ray"
    assert _config("--vec-env", "ray").ray_address == ""


def test_the_recipes_folder_is_the_default_out_and_out_replaces_it() -> None:
    parse = build_parser().parse_args
    assert out_dir(parse(["train", "--recipe", "ppo_offroad_nav_v1"])) == "outputs/ppo_offroad_nav_v1"
    assert (
        out_dir(parse(["train", "--recipe", "ppo_offroad_nav_v1", "--out", "outputs/train"]))
        == "outputs/train"
    )
    assert out_dir(parse(["train"])) == "outputs/train"


def test_a_bad_recipe_exits_2_naming_the_field(tmp_path: Path, capsys) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(RECIPE.replace("steps = 40", "steps = -1"))
    assert main(["train", "--recipe", str(path)]) == 2
    assert "train.warm_start.steps: must be an int >= 0, got -1" in capsys.readouterr().err
    assert main(["train", "--recipe", "no_such_recipe"]) == 2
    assert "no shipped recipe 'no_such_recipe'" in capsys.readouterr().err


def test_a_recipe_runs_end_to_end_and_says_how_to_judge_its_policy(tmp_path: Path, capsys) -> None:
    path = tmp_path / "short.toml"
    path.write_text(RECIPE)
    out = tmp_path / "run"
    assert main(["-q", "train", "--recipe", str(path), "--out", str(out)]) == 0
    result, judged = capsys.readouterr().out.splitlines()
    assert result.startswith(f"model={out / 'model.zip'} steps=64 ")
    policy = out / "warm_start.zip"
    assert judged == (
        f"policy={policy} judge: negobs eval policy {policy} "
        "--first-seed 2000000 --seeds 3 --filter off --workers 2"
    )
    assert policy.is_file()
    record = json.loads((out / "train.json").read_text())
    assert record["code"].startswith(negobs_gym.__version__)  # what a shipped record names
    assert record["config"]["seed"] == 3 and record["config"]["warm_start"]["steps"] == 40
    assert record["warm_start"]["demonstration_steps"] >= 40


@pytest.mark.parametrize("flag", ["--steps", "--seed"])
def test_each_value_option_beside_a_recipe_is_noted_as_given(flag: str) -> None:
    from negobs_gym.cli.train import GIVEN

    args = build_parser().parse_args(["train", "--recipe", "ppo_offroad_nav_v1", flag, "5"])
    assert getattr(args, GIVEN) == {flag.removeprefix("--")}
