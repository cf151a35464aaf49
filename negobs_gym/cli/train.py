"""``negobs train``: train a navigation policy (PPO or SAC) on a negobs env; see docs/training.md.

Runs :func:`negobs_gym.policies.training.train` and prints one line, ``model=<path> steps=<n>
wall_s=<s> steps_per_s=<r>`` followed by the last evaluation's figures.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging

from negobs_gym.cli.common import add_set_option, non_negative_int, positive_int
from negobs_gym.policies.config import (
    ALGORITHMS,
    DEMONSTRATORS,
    SOURCES,
    VEC_ENVS,
    TrainConfig,
    WarmStartConfig,
    steering_head,
)

log = logging.getLogger("negobs_gym.cli.train")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``train``."""
    defaults = TrainConfig()
    parser = subparsers.add_parser(
        "train",
        help="train a policy (PPO/SAC, grid CNN) with logs, evaluation on unseen seeds, checkpoints",
        description="Trains a MultiInputPolicy with the grid CNN extractor on an env id, a shipped "
        "scenario or a scenario TOML file. Writes model.zip, checkpoints/, eval.csv, logs/ (SB3 CSV, "
        "TensorBoard when installed) and train.json under --out. The model loads in 'negobs eval policy'.",
    )
    parser.add_argument(
        "--env",
        default=defaults.env,
        help="env id, shipped scenario name or scenario TOML path (default: %(default)s)",
    )
    parser.add_argument(
        "--algo",
        type=str.upper,
        choices=ALGORITHMS,
        default=defaults.algo,
        help="stable-baselines3 algorithm (default: %(default)s)",
    )
    parser.add_argument(
        "--source",
        choices=SOURCES,
        default=defaults.source,
        help="observation: the detectors' grid, the ground-truth grid, or the state vector only "
        "(default: %(default)s)",
    )
    parser.add_argument("--filter", action="store_true", help="train and evaluate behind the Eq. 18 filter")
    parser.add_argument(
        "--stop-for-positive",
        action="store_true",
        help="with --filter: the filter also stops for the grid's positive-obstacle cells",
    )
    parser.add_argument("--steps", type=positive_int, default=defaults.steps, help="total env steps")
    parser.add_argument("--envs", type=positive_int, default=defaults.envs, help="parallel envs (processes)")
    parser.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        default=defaults.vec_env,
        help="vector env with --envs > 1: build_ahead (SB3's subproc whose idle workers build their "
        "next episode's world), subproc, or prefetch (spare processes reset the next episodes "
        "beforehand); docs/performance.md (default: %(default)s)",
    )
    parser.add_argument("--seed", type=non_negative_int, default=defaults.seed, help="seed (default: 0)")
    parser.add_argument(
        "--steering-modes",
        type=positive_int,
        default=defaults.head.modes,
        metavar="K",
        help="PPO: the policy proposes K scored steering values and drives the best-scored one, "
        "so a clone keeps a pass to the left and one to the right apart (1: one Gaussian mean; "
        "default: %(default)s)",
    )
    parser.add_argument(
        "--steering-bins",
        type=float,
        nargs="+",
        default=(),
        metavar="EDGE",
        help="with the K candidates of --steering-modes (or K = edges + 1 without it): candidate k "
        "learns the steering labels between edges k-1 and k (e.g. -0.3 0.3: pass left, straight "
        "on, pass right) instead of those nearest to it",
    )
    parser.add_argument("--out", default="outputs/train", help="output directory (default: %(default)s)")
    parser.add_argument("--resume", action="store_true", help="continue from the latest checkpoint in --out")
    group = parser.add_argument_group("evaluation and checkpoints")
    group.add_argument(
        "--eval-every",
        type=non_negative_int,
        default=defaults.eval_every,
        help="env steps between evaluations, 0 = only at the end (default: %(default)s)",
    )
    group.add_argument(
        "--eval-episodes",
        type=positive_int,
        default=defaults.eval_episodes,
        help="episodes per evaluation, on unseen seeds (default: %(default)s)",
    )
    group.add_argument(
        "--eval-seed",
        type=non_negative_int,
        default=defaults.eval_seed,
        help="first evaluation seed; keep it apart from the seeds of a later 'negobs eval policy' "
        "when you pick a checkpoint by these evaluations (default: %(default)s)",
    )
    group.add_argument(
        "--checkpoint-every",
        type=non_negative_int,
        default=defaults.checkpoint_every,
        help="env steps between checkpoints, 0 = none (default: %(default)s)",
    )
    group = parser.add_argument_group("algorithm")
    group.add_argument(
        "--n-steps", type=positive_int, default=defaults.n_steps, help="PPO rollout per env (default: 256)"
    )
    group.add_argument("--batch-size", type=positive_int, default=defaults.batch_size, help="minibatch size")
    group.add_argument("--learning-rate", type=float, default=defaults.learning_rate, help="Adam step size")
    group.add_argument(
        "--warm-start-steps",
        type=non_negative_int,
        default=defaults.warm_start.steps,
        help="PPO: first behaviour-clone a scripted driver on this many demonstration steps "
        "(0 = from scratch; default: %(default)s)",
    )
    group.add_argument(
        "--warm-start-driver",
        choices=DEMONSTRATORS,
        default=defaults.warm_start.driver,
        help="the demonstrator: pure_pursuit follows the centre line; track_planner passes the "
        "ground-truth obstacles on the track (OffroadNav-v2) (default: %(default)s)",
    )
    group.add_argument(
        "--dagger-rounds",
        type=non_negative_int,
        default=defaults.warm_start.dagger_rounds,
        help="after the clone, rounds of DAgger: the policy drives --warm-start-steps more steps, "
        "the driver labels them, the policy is refitted on all (default: %(default)s)",
    )
    group.add_argument(
        "--planner-sight-m",
        type=float,
        default=defaults.warm_start.planner_sight_m,
        help="with --warm-start-driver track_planner: how far ahead it sees obstacles, planning "
        "again as each comes into sight (0 = the whole course; 14 = OffroadNav-v2's oracle range; "
        "default: %(default)s)",
    )
    group.add_argument(
        "--planner-horizon-m",
        type=float,
        default=defaults.warm_start.planner_horizon_m,
        help="with --warm-start-driver track_planner: > 0 plans again at every step from the car, "
        "this far ahead, so each label depends only on what the policy can know (e.g. 30 with "
        "--planner-sight-m 14; 0 = one path, replanned when the car strays; default: %(default)s)",
    )
    group.add_argument(
        "--mirror-demonstrations",
        action="store_true",
        help="also fit each demonstrated step's mirror image (grid flipped left-right, steering "
        "and lateral state negated)",
    )
    group.add_argument(
        "--hold-out-every",
        type=non_negative_int,
        default=defaults.warm_start.hold_out_every,
        metavar="K",
        help="leave every K-th demonstration episode out of the fit, score it each epoch and keep "
        "the epoch where its loss is lowest (0 = fit on all; default: %(default)s)",
    )
    group.add_argument(
        "--clone-weight-decay",
        type=float,
        default=defaults.warm_start.weight_decay,
        help="weight decay of the behaviour-cloning fit (AdamW; default: %(default)s)",
    )
    group.add_argument(
        "--demonstrations",
        default="",
        metavar="FILE",
        help="start the warm start from an earlier run's OUT/demonstrations.npz instead of "
        "collecting --warm-start-steps new steps (DAgger rounds still collect that many each)",
    )
    group.add_argument(
        "--warm-start-workers",
        type=positive_int,
        default=defaults.warm_start.workers,
        metavar="N",
        help="processes that drive the demonstration episodes, each with its own env; the "
        "steps are the same for any N (default: %(default)s)",
    )
    group.add_argument(
        "--strong-steer-repeats",
        type=positive_int,
        default=defaults.warm_start.strong_steer_repeats,
        metavar="N",
        help="fit each demonstrated step that steers harder than --strong-steer (a pass) N times "
        "per epoch (default: %(default)s)",
    )
    group.add_argument(
        "--strong-steer",
        type=float,
        default=defaults.warm_start.strong_steer,
        help="|steering label| above which a demonstrated step counts as a pass (default: %(default)s)",
    )
    group.add_argument(
        "--action-std",
        type=float,
        default=None,
        help=f"action std after the warm start (default: {defaults.warm_start.action_std}), or of the "
        "--init model (default: the model's)",
    )
    group.add_argument(
        "--critic-warmup-steps",
        type=non_negative_int,
        default=defaults.critic_warmup_steps,
        help="PPO: only the value function learns for this many env steps, the actor stays as "
        "cloned or initialised (default: %(default)s)",
    )
    group.add_argument(
        "--target-kl",
        type=float,
        default=defaults.target_kl,
        help="PPO: stop an update's epochs once the KL to the rollout's policy passes 1.5x this "
        "(0 = no limit; default: %(default)s)",
    )
    group.add_argument(
        "--init",
        default="",
        metavar="MODEL",
        help="start from this trained model (a .zip or a shipped policy's name) instead of a new "
        "network, e.g. oracle first, then --source detector --filter; the run counts steps from 0 "
        "and evaluates once before training",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_set_option(parser)
    parser.set_defaults(handler=run_train)


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The :class:`TrainConfig` of the parsed command line."""
    defaults = WarmStartConfig()
    return TrainConfig(
        env=args.env,
        algo=args.algo,
        source=args.source,
        filter=args.filter,
        stop_for_positive=args.stop_for_positive,
        steps=args.steps,
        envs=args.envs,
        vec_env=args.vec_env,
        seed=args.seed,
        eval_every=args.eval_every,
        eval_episodes=args.eval_episodes,
        eval_seed=args.eval_seed,
        checkpoint_every=args.checkpoint_every,
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        learning_rate=args.learning_rate,
        head=steering_head(args.steering_modes, args.steering_bins),
        warm_start=WarmStartConfig(
            steps=args.warm_start_steps,
            driver=args.warm_start_driver,
            dagger_rounds=args.dagger_rounds,
            planner_sight_m=args.planner_sight_m,
            planner_horizon_m=args.planner_horizon_m,
            mirror=args.mirror_demonstrations,
            hold_out_every=args.hold_out_every,
            demonstrations=args.demonstrations,
            workers=args.warm_start_workers,
            strong_steer=args.strong_steer,
            strong_steer_repeats=args.strong_steer_repeats,
            weight_decay=args.clone_weight_decay,
            action_std=defaults.action_std if args.action_std is None else args.action_std,
        ),
        init_model=args.init,
        init_action_std=args.action_std if args.init and args.action_std is not None else 0.0,
        critic_warmup_steps=args.critic_warmup_steps,
        target_kl=args.target_kl,
        progress=not args.no_progress,
    )


def run_train(args: argparse.Namespace) -> int:
    """Train; print the result line."""
    from negobs_gym.policies.training import train
    from negobs_gym.scenarios import describe_overrides, env_with_overrides

    config = config_from_args(args)
    label_env = config.env  # the env as named, before --set writes its scenario
    label = describe_overrides(config.env, args.overrides)
    if args.overrides:  # the changed scenario, written to OUT/scenario.toml, is what trains
        config = dataclasses.replace(config, env=env_with_overrides(config.env, args.overrides, args.out))
    log.info(
        "training %s on %s (%s%s), %d steps, %d env(s) -> %s",
        config.algo,
        label,
        config.source,
        (", filter" + (" + positive" if config.stop_for_positive else "")) if config.filter else "",
        config.steps,
        config.envs,
        args.out,
    )
    result = train(config, args.out, resume=args.resume, fitted_on=(label_env, args.overrides))
    e = result.last_eval
    print(
        f"model={result.model_path} steps={result.steps} wall_s={result.wall_s:.1f} "
        f"steps_per_s={result.steps_per_s:.1f} eval_goal={int(e['goal'])}/{int(e['episodes'])} "
        f"eval_entries={int(e['entries'])} eval_collisions={int(e['collisions'])} "
        f"eval_off_track={int(e['off_track'])} "
        f"eval_mean_progress_m={e['mean_progress_m']:.2f} eval_vetoes={int(e['vetoes'])}"
    )
    return 0
