"""``negobs train``: train a navigation policy (PPO or SAC) on a negobs env; see docs/training.md.

Runs :func:`negobs_gym.policies.training.train` and prints one line, ``model=<path> steps=<n>
wall_s=<s> steps_per_s=<r>`` followed by the last evaluation's figures.

Each option is one row of :data:`OPTIONS`: a :class:`~negobs_gym.policies.config.TrainConfig`
setting by its dotted path (``warm_start.steps``), whose default and kind the help shows, or a
scenario setting by its ``--set`` path (``run.filter``): ``--source``, ``--filter`` and
``--stop-for-positive`` are short names of ``--set`` assignments, applied before the ``--set``
ones.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from collections import defaultdict
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from negobs_gym.cli.common import add_set_option, non_negative_int, positive_int
from negobs_gym.policies.config import (
    ALGORITHMS,
    DEMONSTRATORS,
    SOURCES,
    TRAINING_DEFAULTS,
    VEC_ENVS,
    TrainConfig,
    source_settings,
)
from negobs_gym.policies.recipes import Recipe, load_recipe

log = logging.getLogger("negobs_gym.cli.train")

#: How a row's target names a scenario setting (a ``--set`` path) instead of a TrainConfig one.
SET = "--set "


@dataclass(frozen=True)
class Option:
    """One ``negobs train`` option.

    Attributes:
        flag: The option, ``--steps``.
        target: Where its value goes: a :class:`TrainConfig` setting by its dotted path
            (``warm_start.steps``), or ``"--set PATH"``, a scenario setting (``--set run.filter``).
        help: What it does; the TrainConfig default is added.
        group: The ``--help`` section (None: the first).
        means: For a value that stands for more than ``target=value``: the (target, value) pairs
            it sets instead (``--source state``).
        kwargs: argparse's own (``type``, ``choices``, ``action``, ``metavar``, ``nargs``); a
            TrainConfig setting's type is its default's when not given.
    """

    flag: str
    target: str
    help: str
    group: str | None = None
    means: Mapping[Any, tuple[tuple[str, Any], ...]] = field(default_factory=dict)
    kwargs: Mapping[str, Any] = field(default_factory=dict)

    @property
    def dest(self) -> str:
        return self.flag.removeprefix("--").replace("-", "_")

    @property
    def sets_scenario(self) -> bool:
        return self.target.startswith(SET)


def default_of(path: str, config: Any = None) -> Any:
    """The value of the TrainConfig setting at dotted ``path`` in ``config`` (default: TrainConfig())."""
    value = TrainConfig() if config is None else config
    for key in path.split("."):
        value = getattr(value, key)
    return value


EVAL = "evaluation and checkpoints"
ALGO = "algorithm"
WARM = "warm start (behaviour cloning, PPO)"
SCENE = "scenario settings (short names of --set assignments)"


def _source_means() -> dict[str, tuple[tuple[str, Any], ...]]:
    """What each ``--source`` sets (:func:`~negobs_gym.policies.config.source_settings`): its
    ``--set`` assignment and the policy's ``grid_input``."""
    means = {}
    for source in SOURCES:
        overrides, grid_input = source_settings(source)
        pairs = tuple((SET + text.partition("=")[0], text.partition("=")[2]) for text in overrides)
        means[source] = (*pairs, ("grid_input", grid_input))
    return means


#: Every option of ``negobs train`` but ``--out``, ``--resume`` and ``--set``.
OPTIONS: tuple[Option, ...] = (
    Option("--env", "env", "env id, shipped scenario name or scenario TOML path"),
    Option(
        "--algo", "algo", "stable-baselines3 algorithm", kwargs={"type": str.upper, "choices": ALGORITHMS}
    ),
    Option("--steps", "steps", "total env steps", kwargs={"type": positive_int}),
    Option("--envs", "envs", "parallel envs (processes)", kwargs={"type": positive_int}),
    Option(
        "--vec-env",
        "vec_env",
        "vector env with --envs > 1: build_ahead (SB3's subproc whose idle workers build their "
        "next episode's world), subproc, or prefetch (spare processes reset the next episodes "
        "beforehand); docs/performance.md",
        kwargs={"choices": VEC_ENVS},
    ),
    Option("--seed", "seed", "seed of the algorithm and of the envs' first resets"),
    Option(
        "--steering-modes",
        "head.modes",
        "PPO: the policy proposes K scored steering values and drives the best-scored one, so a "
        "clone keeps a pass to the left and one to the right apart (1: one Gaussian mean)",
        kwargs={"type": positive_int, "metavar": "K"},
    ),
    Option(
        "--steering-bins",
        "head.bin_edges",
        "with the K candidates of --steering-modes (or K = edges + 1 without it): candidate k "
        "learns the steering labels between edges k-1 and k (e.g. -0.3 0.3: pass left, straight "
        "on, pass right) instead of those nearest to it",
        kwargs={"type": float, "nargs": "+", "metavar": "EDGE"},
    ),
    Option(
        "--route-offset-m",
        "head.route_offset_m",
        "PPO: the policy chooses a lateral offset from the route, up to this many metres either "
        "way, and steers towards it by pure pursuit (0: it outputs the steering itself)",
        kwargs={"type": float, "metavar": "M"},
    ),
    Option(
        "--source",
        f"{SET}observation.source",
        "the grid: the detectors', the ground truth's, the detectors' error model's (pem, "
        "docs/pem.md), or none in the policy's input (state: the "
        "state vector only; the env computes the oracle's grid, for the filter) (default: the "
        "scenario's own)",
        SCENE,
        means=_source_means(),
        kwargs={"choices": SOURCES},
    ),
    Option(
        "--filter",
        f"{SET}run.filter",
        "train and evaluate behind the Eq. 18 safety filter (a training run starts from "
        f"{' '.join(TRAINING_DEFAULTS)}, whatever the scene's [run] table says)",
        SCENE,
        kwargs={"action": "store_true"},
    ),
    Option(
        "--stop-for-positive",
        f"{SET}filter.stop_for_positive",
        "with --filter: the filter also stops for the grid's positive-obstacle cells",
        SCENE,
        kwargs={"action": "store_true"},
    ),
    Option("--eval-every", "eval_every", "env steps between evaluations, 0 = only at the end", EVAL),
    Option(
        "--eval-episodes",
        "eval_episodes",
        "episodes per evaluation, on unseen seeds",
        EVAL,
        kwargs={"type": positive_int},
    ),
    Option(
        "--eval-seed",
        "eval_seed",
        "first evaluation seed; keep it apart from the seeds of a later 'negobs eval policy' when "
        "you pick a checkpoint by these evaluations",
        EVAL,
    ),
    Option("--checkpoint-every", "checkpoint_every", "env steps between checkpoints, 0 = none", EVAL),
    Option("--n-steps", "n_steps", "PPO rollout per env", ALGO, kwargs={"type": positive_int}),
    Option("--batch-size", "batch_size", "minibatch size", ALGO, kwargs={"type": positive_int}),
    Option("--learning-rate", "learning_rate", "Adam step size", ALGO),
    Option(
        "--critic-warmup-steps",
        "critic_warmup_steps",
        "PPO: only the value function learns for this many env steps, the actor stays as cloned "
        "or initialised",
        ALGO,
    ),
    Option(
        "--target-kl",
        "target_kl",
        "PPO: stop an update's epochs once the KL to the rollout's policy passes 1.5x this (0 = no limit)",
        ALGO,
    ),
    Option(
        "--init",
        "init_model",
        "start from this trained model (a .zip or a shipped policy's name) instead of a new "
        "network, e.g. oracle first, then --source detector --filter; the run counts steps from 0 "
        "and evaluates once before training",
        ALGO,
        kwargs={"metavar": "MODEL"},
    ),
    Option(
        "--action-std",
        "warm_start.action_std",
        f"action std after the warm start (default: {default_of('warm_start.action_std')}); with "
        "--init, the init model's instead (init_action_std; default: the model's own)",
        ALGO,
        kwargs={"type": float, "default": None},  # None: each of the two keeps its default
    ),
    Option(
        "--warm-start-steps",
        "warm_start.steps",
        "first behaviour-clone a scripted driver on this many demonstration steps (0 = from scratch)",
        WARM,
    ),
    Option(
        "--warm-start-driver",
        "warm_start.driver",
        "the demonstrator: pure_pursuit follows the centre line; track_planner passes the "
        "ground-truth obstacles on the track (OffroadTrack-v0); grid_planner the obstacles the grid shows",
        WARM,
        kwargs={"choices": DEMONSTRATORS},
    ),
    Option(
        "--dagger-rounds",
        "warm_start.dagger_rounds",
        "after the clone, rounds of DAgger: the policy drives --warm-start-steps more steps, the "
        "driver labels them, the policy is refitted on all",
        WARM,
    ),
    Option(
        "--planner-sight-m",
        "warm_start.planner_sight_m",
        "with --warm-start-driver track_planner: how far ahead it sees obstacles, planning again "
        "as each comes into sight (0 = the whole course; 14 = OffroadTrack-v0's oracle range)",
        WARM,
    ),
    Option(
        "--planner-horizon-m",
        "warm_start.planner_horizon_m",
        "with --warm-start-driver track_planner: > 0 plans again at every step from the car, this "
        "far ahead, so each label depends only on what the policy can know (e.g. 30 with "
        "--planner-sight-m 14; 0 = one path, replanned when the car strays)",
        WARM,
    ),
    Option(
        "--mirror-demonstrations",
        "warm_start.mirror",
        "also fit each demonstrated step's mirror image (grid flipped left-right, steering and "
        "lateral state negated)",
        WARM,
    ),
    Option(
        "--hold-out-every",
        "warm_start.hold_out_every",
        "leave every K-th demonstration episode out of the fit, score it each epoch and keep the "
        "epoch where its loss is lowest (0 = fit on all)",
        WARM,
        kwargs={"metavar": "K"},
    ),
    Option("--clone-weight-decay", "warm_start.weight_decay", "weight decay of the fit (AdamW)", WARM),
    Option(
        "--demonstrations",
        "warm_start.demonstrations",
        "start the warm start from an earlier run's OUT/demonstrations.npz instead of collecting "
        "--warm-start-steps new steps (DAgger rounds still collect that many each)",
        WARM,
        kwargs={"metavar": "FILE"},
    ),
    Option(
        "--warm-start-workers",
        "warm_start.workers",
        "processes that drive the demonstration episodes, each with its own env; the steps are "
        "the same for any N",
        WARM,
        kwargs={"type": positive_int, "metavar": "N"},
    ),
    Option(
        "--strong-steer-repeats",
        "warm_start.strong_steer_repeats",
        "fit each demonstrated step that steers harder than --strong-steer (a pass) N times per epoch",
        WARM,
        kwargs={"type": positive_int, "metavar": "N"},
    ),
    Option(
        "--strong-steer",
        "warm_start.strong_steer",
        "|steering label| above which a demonstrated step counts as a pass",
        WARM,
    ),
    Option("--no-progress", "progress", "no progress bar"),
)


def _argparse_kwargs(option: Option) -> dict[str, Any]:
    """argparse's arguments of ``option``: a TrainConfig setting's default, and its type from it."""
    kwargs = dict(option.kwargs)
    if option.sets_scenario:
        value = "true" if kwargs.get("action") == "store_true" else option.dest.upper()
        return {"help": f"{option.help}; = --set {option.target.removeprefix(SET)}={value}", **kwargs}
    if "default" in kwargs:  # the row says what its default means
        return {"help": option.help, **kwargs}
    default = default_of(option.target)
    if isinstance(default, bool):  # a switch that turns the default over
        kwargs.setdefault("action", "store_false" if default else "store_true")
        return {"help": option.help, "default": default, **kwargs}
    if not isinstance(default, tuple):
        kwargs.setdefault("type", non_negative_int if isinstance(default, int) else type(default))
    shown = f"{option.help} (default: %(default)s)" if default not in ("", ()) else option.help
    return {"help": shown, "default": default, **kwargs}


#: The namespace attribute holding the ``dest`` of each option the command line gave (with a
#: recipe only those replace the recipe's settings).
GIVEN = "given_options"


def _marking(action: type[argparse.Action]) -> type[argparse.Action]:
    """``action`` that also notes its ``dest`` in the namespace's :data:`GIVEN` set when used."""

    class Marking(action):  # type: ignore[misc, valid-type]
        def __call__(self, parser, namespace, values, option_string=None) -> None:  # type: ignore[no-untyped-def]
            super().__call__(parser, namespace, values, option_string)
            given = set(getattr(namespace, GIVEN, None) or ())
            setattr(namespace, GIVEN, given | {self.dest})

    return Marking


_ACTIONS: dict[str | None, type[argparse.Action]] = {
    None: _marking(argparse._StoreAction),
    "store_true": _marking(argparse._StoreTrueAction),
    "store_false": _marking(argparse._StoreFalseAction),
}


def _marked(kwargs: dict[str, Any]) -> dict[str, Any]:
    """argparse keyword arguments whose action notes that the option was given (:data:`GIVEN`)."""
    return {**kwargs, "action": _ACTIONS[kwargs.get("action")]}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``train``: ``--recipe``, one argument per row of :data:`OPTIONS`, then ``--ray``,
    ``--out``, ``--resume``, ``--set``."""
    parser = subparsers.add_parser(
        "train",
        help="train a policy (PPO/SAC, grid CNN) with logs, evaluation on unseen seeds, checkpoints",
        description="Trains a MultiInputPolicy with the grid CNN extractor on an env id, a shipped "
        "scenario or a scenario TOML file, with its settings changed by --set (and the short names "
        "below). Writes model.zip, checkpoints/, eval.csv, logs/ (SB3 CSV, TensorBoard when "
        "installed), scenario.toml and train.json under --out. The model loads in 'negobs eval policy'.",
    )
    parser.add_argument(
        "--recipe",
        metavar="NAME",
        help="train as a recipe file says (a shipped recipe's name, e.g. a shipped policy's, or a "
        "TOML path; docs/training.md, 'Recipes'); the options given beside it replace its settings, "
        "and --set adds to its overrides",
    )
    groups: dict[str | None, Any] = {None: parser}
    for option in OPTIONS:
        if option.group not in groups:
            groups[option.group] = parser.add_argument_group(option.group)
        kwargs = _marked(_argparse_kwargs(option))
        groups[option.group].add_argument(option.flag, dest=option.dest, **kwargs)
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        action=_ACTIONS[None],
        help="the envs as Ray actors (pip install 'negobs_gym[ray]'), the same rollouts as local "
        "processes; no ADDRESS starts a local instance (= --vec-env ray)",
    )
    parser.add_argument(
        "--out",
        default="outputs/train",
        action=_ACTIONS[None],
        help="output directory (default: %(default)s; with --recipe NAME: outputs/NAME)",
    )
    parser.add_argument("--resume", action="store_true", help="continue from the latest checkpoint in --out")
    add_set_option(parser)
    parser.set_defaults(handler=run_train)


def _settings(args: argparse.Namespace) -> tuple[dict[str, Any], list[str]]:
    """The TrainConfig settings (dotted path -> value) and the ``--set`` assignments the parsed
    options stand for, in :data:`OPTIONS`' order; the command's own ``--set`` come last."""
    settings: dict[str, Any] = {}
    assignments: list[str] = []
    for option in OPTIONS:
        value = getattr(args, option.dest)
        if option.sets_scenario and value in (None, False):
            continue  # not given: the scenario's own setting
        meant = option.means.get(value) if option.means else None
        for target, setting in meant or ((option.target, value),):
            if target.startswith(SET):
                assignments.append(f"{target.removeprefix(SET)}={_toml(setting)}")
            else:
                settings[target] = setting
    return settings, [*assignments, *args.overrides]


def _toml(value: Any) -> str:
    """A ``--set`` VALUE: TOML's ``true``/``false`` for a switch, else the text as typed."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def _derived(settings: dict[str, Any], base: TrainConfig) -> dict[str, Any]:
    """The two settings one option gives another's meaning: ``--steering-bins`` alone give
    their number of candidates, and ``--action-std`` with ``--init`` (or a recipe's init model)
    sets the init model's std."""
    edges = settings.get("head.bin_edges", ())
    if edges and settings.get("head.modes", base.head.modes) == 1:
        settings["head.modes"] = len(edges) + 1
    action_std = settings.pop("warm_start.action_std", None)
    if action_std is not None:
        init = settings.get("init_model", base.init_model)
        settings["init_action_std" if init else "warm_start.action_std"] = action_std
    return settings


def with_settings(config: Any, settings: Mapping[str, Any]) -> Any:
    """``config`` (a frozen config dataclass) with each setting at its dotted path changed; each
    dataclass on the way is rebuilt once, so its own checks see all of its new values together."""
    own: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = defaultdict(dict)
    for path, value in settings.items():
        key, _, rest = path.partition(".")
        if rest:
            nested[key][rest] = value
        else:
            own[key] = tuple(value) if isinstance(value, list) else value
    for key, inner in nested.items():
        own[key] = with_settings(getattr(config, key), inner)
    return dataclasses.replace(config, **own)


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The :class:`TrainConfig` of the parsed command line: with ``--recipe``, the recipe's
    config with the options given beside it changed and the command's ``--set`` assignments
    (its short names' first) after the recipe's overrides; else TrainConfig's defaults with
    every option's value.

    Raises:
        ConfigError: a value the configs refuse (its field), or a bad recipe (its path in the file).
    """
    settings, overrides = _settings(args)
    base = TrainConfig()
    recipe = _recipe(args)
    if recipe is not None:
        base = recipe.train
        given = getattr(args, GIVEN, None) or set()
        targets = {o.target for o in OPTIONS if o.dest in given}
        settings = {k: v for k, v in settings.items() if k in targets or _given_by_means(k, given)}
        overrides = [*base.overrides, *overrides]
    if getattr(args, "ray", None) is not None:
        settings.update({"vec_env": "ray", "ray_address": "" if args.ray == "local" else args.ray})
    return with_settings(base, {**_derived(settings, base), "overrides": tuple(overrides)})


def _given_by_means(target: str, given: set[str]) -> bool:
    """Whether ``target`` is set by a given option's meaning (``--source state``: grid_input)."""
    return any(
        option.dest in given and any(t == target for m in option.means.values() for t, _ in m)
        for option in OPTIONS
    )


def _recipe(args: argparse.Namespace) -> Recipe | None:
    """The parsed command's ``--recipe``, loaded (None without one)."""
    name = getattr(args, "recipe", None)
    return load_recipe(name) if name else None


def out_dir(args: argparse.Namespace) -> str:
    """The run's folder: ``--out``, or with a recipe and no ``--out``, ``outputs/<recipe name>``."""
    recipe = _recipe(args)
    if recipe is not None and "out" not in (getattr(args, GIVEN, None) or set()):
        return f"outputs/{recipe.name}"
    return str(args.out)


def run_train(args: argparse.Namespace) -> int:
    """Train; print the result line."""
    from negobs_gym.policies.training import train
    from negobs_gym.spec import describe_overrides

    config = config_from_args(args)
    out = out_dir(args)
    log.info(
        "training %s on %s%s, %d steps, %d env(s)%s -> %s",
        config.algo,
        describe_overrides(config.env, config.overrides),
        "" if config.grid_input else " (state only)",
        config.steps,
        config.envs,
        " on Ray" if config.vec_env == "ray" else "",
        out,
    )
    result = train(config, out, resume=args.resume)
    e = result.last_eval
    print(
        f"model={result.model_path} steps={result.steps} wall_s={result.wall_s:.1f} "
        f"steps_per_s={result.steps_per_s:.1f} eval_goal={int(e['goal'])}/{int(e['episodes'])} "
        f"eval_entries={int(e['entries'])} eval_collisions={int(e['collisions'])} "
        f"eval_off_track={int(e['off_track'])} "
        f"eval_mean_progress_m={e['mean_progress_m']:.2f} eval_vetoes={int(e['vetoes'])}"
    )
    recipe = _recipe(args)
    if recipe is not None:
        print(f"policy={Path(out) / recipe.policy_file} judge: {recipe.eval_command(out)}")
    return 0
