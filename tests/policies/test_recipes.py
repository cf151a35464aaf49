"""Training recipes: the shipped ones load, each shipped policy has the recipe its record's config
names, and a bad recipe is a ConfigError naming its path in the file."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from negobs_gym.drivers.zoo import baseline_names, baseline_record
from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import TrainConfig, WarmStartConfig, config_from_record
from negobs_gym.policies.recipes import (
    Recipe,
    RecipeEvaluation,
    load_recipe,
    recipe_names,
    recipe_to_toml,
)

GOOD = """
[recipe]
description = "a short clone"
policy_file = "warm_start.zip"

[train]
env = "negobs_gym/Braking-v1"
overrides = ["observation.source=oracle"]
steps = 64
seed = 3

[train.warm_start]
steps = 40
mirror = true

[evaluation]
first_seed = 2000000
seeds = 5
filter = "on"
"""


def test_a_recipe_file_holds_the_whole_run(tmp_path: Path) -> None:
    path = tmp_path / "mine.toml"
    path.write_text(GOOD)
    recipe = load_recipe(str(path))
    assert recipe == Recipe(
        name="mine",
        description="a short clone",
        policy_file="warm_start.zip",
        train=TrainConfig(
            env="negobs_gym/Braking-v1",
            overrides=("observation.source=oracle",),
            steps=64,
            seed=3,
            warm_start=WarmStartConfig(steps=40, mirror=True),
        ),
        evaluation=RecipeEvaluation(first_seed=2_000_000, seeds=5, filter="on"),
    )
    assert recipe.eval_command("out") == (
        f"negobs eval policy {Path('out') / 'warm_start.zip'} "
        "--first-seed 2000000 --seeds 5 --filter on --workers 2"
    )
    # written out with every setting, it reads back to itself
    (tmp_path / "again.toml").write_text(recipe_to_toml(recipe))
    assert load_recipe(tmp_path / "again.toml") == dataclasses.replace(recipe, name="again")
    # a policy fitted on one grid and judged on another: the judge names the grid
    path.write_text(GOOD.replace('filter = "on"', 'filter = "on"\nsource = "detector"'))
    assert load_recipe(path).eval_command("out") == (
        f"negobs eval policy {Path('out') / 'warm_start.zip'} --source detector "
        "--first-seed 2000000 --seeds 5 --filter on --workers 2"
    )


def test_a_recipe_configures_its_demonstrator(tmp_path: Path) -> None:
    path = tmp_path / "heading.toml"
    path.write_text(
        GOOD.replace("mirror = true", 'mirror = true\ndriver = "grid_planner"')
        + "\n[train.warm_start.driver_settings.planner]\nbend_steps = 1\n"
    )
    recipe = load_recipe(path)
    assert recipe.train.warm_start.driver_settings == {"planner": {"bend_steps": 1}}
    (tmp_path / "again.toml").write_text(recipe_to_toml(recipe))
    assert load_recipe(tmp_path / "again.toml") == dataclasses.replace(recipe, name="again")


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (("[evaluation]", "[evaluations]"), "evaluations"),
        (("seed = 3", "seed = 3\nsources = 'pem'"), "train.sources"),
        (("steps = 40", "steps = -40"), "train.warm_start.steps"),
        (("steps = 40", "steps = 40\nwarp = 1"), "train.warm_start.warp"),
        (("steps = 64", "steps = 'many'"), "train.steps"),
        (('algo = "PPO"', ""), None),  # not in GOOD: no change, loads
        (('filter = "on"', 'filter = "sometimes"'), "evaluation.filter"),
        (("seeds = 5", "seeds = 0"), "evaluation.seeds"),
        (('filter = "on"', 'filter = "on"\nsource = "radar"'), "evaluation.source"),
        (('policy_file = "warm_start.zip"', 'policy_file = "best.zip"'), "recipe.policy_file"),
        (('description = "a short clone"', 'author = "me"'), "recipe.author"),
        (("steps = 40\nmirror = true", "mirror = true"), "recipe.policy_file"),  # no clone to ship
        (('env = "negobs_gym/Braking-v1"', 'env = ""'), "train.env"),
        (("[train]", "[train]\noverrides = 3"), "recipe"),  # a key twice: bad TOML
        (("mirror = true", "mirror = true\ndriver_settings = {a = 3}"), "train.warm_start.driver_settings"),
    ],
)
def test_a_bad_recipe_names_its_field(tmp_path: Path, edit: tuple[str, str], field: str | None) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(*edit))
    if field is None:
        assert load_recipe(path).train.algo == "PPO"
        return
    with pytest.raises(ConfigError) as error:
        load_recipe(path)
    assert error.value.field == field


def test_an_unknown_recipe_names_the_shipped_ones(tmp_path: Path) -> None:
    with pytest.raises(
        ConfigError, match=r"recipe: no recipe file and no shipped recipe 'nothing'.*ppo_offroad"
    ):
        load_recipe("nothing")
    with pytest.raises(ConfigError, match="recipe: no recipe file at"):
        load_recipe(str(tmp_path / "missing.toml"))
    path = tmp_path / "no_train.toml"
    path.write_text("[recipe]\ndescription = 'x'\n")
    with pytest.raises(ConfigError, match="train: missing"):
        load_recipe(path)


@pytest.mark.parametrize("name", recipe_names())
def test_each_shipped_recipe_loads(name: str) -> None:
    recipe = load_recipe(name)
    assert recipe.name == name and recipe.description
    assert (
        load_recipe(Path(__file__).parents[2] / "negobs_gym" / "policies" / "recipes" / f"{name}.toml")
        == recipe
    )


@pytest.mark.parametrize("name", baseline_names())
def test_each_shipped_policy_is_its_recipe_as_its_record_says(name: str) -> None:
    """A shipped policy's recipe is named as it, and its run is the config the record holds:
    the record's settings still parse (config_from_record), and equal the recipe's."""
    record = baseline_record(name)
    recipe = load_recipe(name)
    assert record["recipe"] == f"negobs train --recipe {name}"
    assert config_from_record(record["config"]) == recipe.train
    assert recipe.train.env == record["env"]
    assert set(record.get("set", ())) <= set(recipe.train.overrides)
    # a behaviour clone (no RL step) ships the clone, and its name says so
    assert (recipe.policy_file == "warm_start.zip") == (record["steps"] == 0) == name.startswith("bc_")
