"""Training recipes: one TOML file holds everything one ``negobs train`` run needs.

A recipe is the :class:`~negobs_gym.policies.config.TrainConfig` of a run (env or scene, its
``--set`` overrides such as ``observation.source``, the algorithm and its hyperparameters, the
warm start, steps and seeds), which output file is the policy, and the unseen seeds it is judged
on. Each shipped policy has one, named as the policy (``negobs_gym/policies/recipes/NAME.toml``),
so ``negobs train --recipe NAME`` recreates it (docs/training.md, "Recipes")::

    [recipe]
    description = "what the run makes"
    policy_file = "model.zip"        # or "warm_start.zip": a clone with no RL step

    [train]                          # TrainConfig's fields; nested configs as sub-tables
    env = "negobs_gym/OffroadTrack-v0"
    overrides = ["observation.source=pem"]
    steps = 64
    seed = 1

    [train.warm_start]
    steps = 40000
    driver = "track_planner"

    [evaluation]                     # negobs eval policy's seeds, apart from the training ones
    first_seed = 1000000
    seeds = 20
    filter = "both"

No torch or gymnasium here: the CLI reads recipes cheaply.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomllib

from negobs_gym.errors import ConfigError, require
from negobs_gym.policies.config import SOURCES, TrainConfig, _from_dict

__all__ = [
    "FILTER_MODES",
    "POLICY_FILES",
    "RECIPE_DIR",
    "Recipe",
    "RecipeEvaluation",
    "load_recipe",
    "recipe_from_dict",
    "recipe_names",
]

RECIPE_DIR = Path(__file__).with_name("recipes")
#: What a run writes that can be the policy: the final model, or the clone before any RL step.
POLICY_FILES: tuple[str, ...] = ("model.zip", "warm_start.zip")
#: ``negobs eval policy --filter``.
FILTER_MODES: tuple[str, ...] = ("off", "on", "both")
#: ``negobs eval policy --source``: the grid sources ("state" has no grid to judge on); "" judges
#: on the grid the policy's record names.
JUDGE_SOURCES: tuple[str, ...] = ("", *(s for s in SOURCES if s != "state"))


@dataclass(frozen=True, kw_only=True)
class RecipeEvaluation:
    """The seeds a recipe's policy is judged on (``negobs eval policy``), never used in training.

    Attributes:
        first_seed: First course seed; 1,000,000 and up is where every shipped policy's record
            was measured (its training and warm-start seeds are small integers).
        seeds: Number of courses.
        filter: ``off``, ``on`` or ``both``: without and/or behind the Eq. 18 safety filter.
        source: The grid it is judged on (``--source``): "" the one it was fitted on, as its record
            names it; ``detector`` for a policy trained on the PEM or oracle grid and judged on
            what the detectors see.
    """

    first_seed: int = 1_000_000
    seeds: int = 20
    filter: str = "both"
    source: str = ""

    def __post_init__(self) -> None:
        require(
            isinstance(self.first_seed, int) and self.first_seed >= 0,
            "first_seed",
            f"must be an int >= 0, got {self.first_seed!r}",
        )
        require(
            isinstance(self.seeds, int) and self.seeds >= 1,
            "seeds",
            f"must be an int >= 1, got {self.seeds!r}",
        )
        require(self.filter in FILTER_MODES, "filter", f"must be one of {FILTER_MODES}, got {self.filter!r}")
        require(
            self.source in JUDGE_SOURCES, "source", f"must be one of {JUDGE_SOURCES}, got {self.source!r}"
        )


@dataclass(frozen=True, kw_only=True)
class Recipe:
    """One training run, as a file.

    Attributes:
        name: The recipe's name (its file's stem): a shipped policy's recipe is named as it.
        description: What the run makes and why it is set up so.
        train: The run's config.
        policy_file: The output file that is the policy (:data:`POLICY_FILES`).
        evaluation: The seeds to judge it on.
    """

    name: str
    description: str = ""
    train: TrainConfig = field(default_factory=TrainConfig)
    policy_file: str = "model.zip"
    evaluation: RecipeEvaluation = field(default_factory=RecipeEvaluation)

    def __post_init__(self) -> None:
        require(isinstance(self.name, str) and bool(self.name), "recipe.name", "must be a non-empty text")
        require(isinstance(self.description, str), "recipe.description", "must be a text")
        require(
            self.policy_file in POLICY_FILES,
            "recipe.policy_file",
            f"must be one of {POLICY_FILES}, got {self.policy_file!r}",
        )
        require(
            self.policy_file != "warm_start.zip" or self.train.warm_start.enabled,
            "recipe.policy_file",
            "warm_start.zip needs a warm start ([train.warm_start] steps or demonstrations)",
        )

    def eval_command(self, out: str | Path) -> str:
        """The ``negobs eval policy`` command that judges the run's policy under ``out``."""
        e = self.evaluation
        source = f" --source {e.source}" if e.source else ""
        return (
            f"negobs eval policy {Path(out) / self.policy_file}{source} --first-seed {e.first_seed} "
            f"--seeds {e.seeds} --filter {e.filter} --workers 2"
        )


def recipe_names() -> list[str]:
    """The recipes shipped in the package, sorted."""
    return sorted(p.stem for p in RECIPE_DIR.glob("*.toml"))


def recipe_path(recipe: str) -> Path:
    """The file of ``recipe``: a path to a TOML file, or a shipped recipe's name.

    Raises:
        ConfigError: neither (field ``recipe``).
    """
    path = Path(recipe)
    if path.suffix == ".toml" or path.is_file():
        require(path.is_file(), "recipe", f"no recipe file at {path}")
        return path
    shipped = RECIPE_DIR / f"{recipe}.toml"
    require(
        shipped.is_file(),
        "recipe",
        f"no recipe file and no shipped recipe {recipe!r}; shipped: {recipe_names()}",
    )
    return shipped


def load_recipe(recipe: str | Path) -> Recipe:
    """The :class:`Recipe` of a shipped name or a TOML path.

    Raises:
        ConfigError: no such recipe (``recipe``), bad TOML (``recipe``, with the parser's line),
            or a bad setting, named by its table path (``train.warm_start.steps``).
    """
    path = recipe_path(str(recipe))
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as error:
        raise ConfigError("recipe", f"{path} is not valid TOML: {error}") from None
    return recipe_from_dict(data, name=path.stem)


_TABLES = ("recipe", "train", "evaluation")


def recipe_from_dict(data: Mapping[str, Any], name: str) -> Recipe:
    """A :class:`Recipe` from its TOML tables (:data:`_TABLES`); ``name`` unless ``recipe.name``
    gives one.

    Raises:
        ConfigError: an unknown table or setting, or a value the configs refuse, named by its
            path in the file (``train.warm_start.steps``, ``evaluation.seeds``, ``recipe.policy_file``).
    """
    unknown = sorted(set(data) - set(_TABLES))
    require(not unknown, unknown[0] if unknown else "", f"no such table; a recipe has {', '.join(_TABLES)}")
    for table in _TABLES:
        require(isinstance(data.get(table, {}), Mapping), table, "must be a table")
    head = dict(data.get("recipe", {}))
    known = {"name", "description", "policy_file"}
    extra = sorted(set(head) - known)
    require(
        not extra,
        f"recipe.{extra[0]}" if extra else "",
        f"no such setting; [recipe] has {', '.join(sorted(known))}",
    )
    require("train" in data, "train", "missing: the run's settings (at least env)")
    train = _from_dict(TrainConfig, _lists_as_tuples(data["train"]), "train", name_errors=True)
    evaluation = _from_dict(RecipeEvaluation, data.get("evaluation", {}), "evaluation", name_errors=True)
    return Recipe(
        name=head.get("name", name),
        description=head.get("description", ""),
        train=train,
        policy_file=head.get("policy_file", "model.zip"),
        evaluation=evaluation,
    )


def _lists_as_tuples(table: Mapping[str, Any]) -> dict[str, Any]:
    """TOML arrays as the tuples the configs hold (nested tables likewise)."""
    return {
        k: (tuple(v) if isinstance(v, list) else _lists_as_tuples(v) if isinstance(v, Mapping) else v)
        for k, v in table.items()
    }


def recipe_to_toml(recipe: Recipe) -> str:
    """``recipe`` as a TOML file that :func:`load_recipe` reads back to it: every TrainConfig
    setting written out, so a later default does not change the run."""
    from negobs_gym.spec.toml_out import dumps_toml

    train = dataclasses.asdict(recipe.train)
    return dumps_toml(
        {
            "recipe": {"description": recipe.description, "policy_file": recipe.policy_file},
            "train": train,
            "evaluation": dataclasses.asdict(recipe.evaluation),
        }
    )
