"""``negobs pem fit|check``: fit a perception-error model of the detector grid and check it.

``fit`` drives detection courses through the env's detector grid (its ``[observation]`` settings
from ``--env`` and ``--set``), fits the PEM's tables and writes its JSON file atomically; ``check``
drives fresh courses with the detector and a PEM side by side, prints every figure and check as
``key=value`` and exits 1 when a check fails (docs/pem.md).
"""

from __future__ import annotations

import argparse
import logging

from negobs_gym.cli.common import add_runner_options, add_set_option, non_negative_int, positive_int

log = logging.getLogger("negobs_gym.cli")

#: The first seed ``check`` drives by default: far from the fit's (0 ..).
CHECK_FIRST_SEED = 1_000_000


def _campaign_options(parser: argparse.ArgumentParser, seeds: int, frames: int, first_seed: int) -> None:
    group = parser.add_argument_group("courses")
    group.add_argument("--seeds", type=positive_int, default=seeds, help="courses (default: %(default)s)")
    group.add_argument(
        "--first-seed",
        type=non_negative_int,
        default=first_seed,
        help="the first course's seed (default: %(default)s)",
    )
    group.add_argument(
        "--frames",
        type=positive_int,
        default=frames,
        help="10 Hz frames of all courses together (default: %(default)s)",
    )
    group.add_argument(
        "--env",
        default=None,
        help="take the detector grid's settings from this env's [observation] (id, scene or TOML; "
        "default: the envs' default observation)",
    )
    group.add_argument(
        "--path-offset-m",
        type=float,
        default=0.0,
        help="drive the courses this far beside the centre line, + right, as a driver passing a pit "
        "closely does (default: %(default)s, the centre line)",
    )
    add_set_option(parser)
    add_runner_options(group, "courses")
    group.add_argument("--no-progress", action="store_true", help="no progress bar")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``pem`` with its ``fit`` and ``check`` commands."""
    parser = subparsers.add_parser(
        "pem",
        help="perception-error model of the detector grid: fit it from the detectors, check it on "
        "fresh courses",
        description="A perception-error model (PEM) of the detector grid's obstacle channels: the "
        "grid source 'pem' (observation.source=pem) draws it from the ground truth at the "
        "oracle's cost. docs/pem.md.",
    )
    commands = parser.add_subparsers(dest="pem_command", metavar="COMMAND", required=True)
    fit = commands.add_parser(
        "fit",
        help="drive courses through the detector grid, fit the PEM, write its JSON file",
        description="Drives detection courses (seeds FIRST..FIRST+N-1) through the detector grid and "
        "writes the fitted PEM to --model (atomically); the per-frame rows stay in --work.",
    )
    fit.add_argument(
        "--model", default="outputs/pem/pem.json", help="PEM file to write (default: %(default)s)"
    )
    fit.add_argument(
        "--work", default="outputs/pem/fit", help="folder of the drives' rows (default: %(default)s)"
    )
    fit.add_argument(
        "--calibrate",
        type=non_negative_int,
        default=1,
        metavar="PASSES",
        help="then drive the same courses with the PEM this many times, each time scaling its "
        "recall per 2 m bin to the detector's there (0: the tables alone; default: %(default)s)",
    )
    fit.add_argument(
        "--false-alarms-into",
        metavar="BASE",
        default=None,
        help="write BASE (a PEM file of the same settings) with only its false-alarm tables "
        "replaced by this fit's, its other tables and calibration kept (implies --calibrate 0)",
    )
    _campaign_options(fit, seeds=8, frames=400, first_seed=0)
    fit.set_defaults(handler=run_fit)
    check = commands.add_parser(
        "check",
        help="detector vs PEM on fresh courses: key=value figures, exit 1 when a check fails",
        description="Drives fresh courses with the detector grid and the PEM on the same poses and "
        "compares recall per 2 m bin, false alarms per km on and off the track, the near-edge "
        "offset and the first-confirmation distance; writes check.txt, summary.json, tables.md and "
        "pem_check.png to --out.",
    )
    check.add_argument(
        "--model",
        default=None,
        help="PEM file (default: the one shipped with the package for the observation's positive channel)",
    )
    check.add_argument("--out", default="outputs/pem/check", help="output folder (default: %(default)s)")
    _campaign_options(check, seeds=4, frames=400, first_seed=CHECK_FIRST_SEED)
    loop = check.add_argument_group("closed loop (the braking campaign, detector vs PEM)")
    loop.add_argument(
        "--braking-seeds",
        type=non_negative_int,
        default=0,
        help="also run the braking campaign (reckless driver + safety filter) on this many seeds, on "
        "the detector grid and on the PEM's (issue 75 asks for >= 100; default: %(default)s, not run)",
    )
    loop.add_argument(
        "--braking-scenarios",
        nargs="+",
        default=["ditch"],
        metavar="SCENARIO",
        help="the braking campaign's scenarios (default: %(default)s)",
    )
    loop.add_argument(
        "--policy",
        default=None,
        metavar="MODEL",
        help="also run this policy (a shipped name, a saved model, or a scripted driver's name such as "
        "track_planner, with --policy-env) on the same unseen seeds on both grids behind the filter, "
        "and check the gap in goal rate (<= 10 points)",
    )
    loop.add_argument(
        "--policy-seeds", type=positive_int, default=20, help="the policy's episodes (default: %(default)s)"
    )
    loop.add_argument(
        "--policy-first-seed",
        type=non_negative_int,
        default=CHECK_FIRST_SEED,
        help="the policy's first seed (default: %(default)s)",
    )
    loop.add_argument(
        "--policy-env",
        default=None,
        help="the env the policy runs on (default: its record's, with the record's --set)",
    )
    loop.add_argument(
        "--no-courses",
        action="store_true",
        help="skip the detection courses (run the closed loops alone; needs --braking-seeds or --policy)",
    )
    check.set_defaults(handler=run_check)


def _observation(args: argparse.Namespace):
    """The detector grid's settings: ``--env``'s observation (or the default) changed by ``--set``."""
    from negobs_gym.errors import ConfigError
    from negobs_gym.spec import ObservationConfig
    from negobs_gym.spec.overrides import apply_overrides, spec_for_env

    if args.env is None:
        if not args.overrides:
            return ObservationConfig()
        raise ConfigError("--set", "needs --env (the scenario whose observation it changes)")
    return apply_overrides(spec_for_env(args.env), args.overrides).observation


def _config(args: argparse.Namespace):
    from negobs_gym.eval.campaign import Backend, RunOptions, import_ray
    from negobs_gym.eval.pem_data import PemCampaignConfig

    if args.ray is not None:
        import_ray()
    options = RunOptions(Backend(workers=args.workers, ray=args.ray), args.resume, not args.no_progress)
    config = PemCampaignConfig(
        seeds=args.seeds,
        first_seed=args.first_seed,
        frames=args.frames,
        observation=_observation(args),
        path_offset_m=args.path_offset_m,
    )
    return config, options


def run_fit(args: argparse.Namespace) -> int:
    """Fit and write the PEM; logs where it is."""
    from negobs_gym.envs.pem import load_pem
    from negobs_gym.eval.pem_fit import fit_pem

    config, options = _config(args)
    log.info(
        "PEM fit: %d courses from seed %d, %d frames -> %s",
        config.seeds,
        config.first_seed,
        config.frames,
        args.model,
    )
    base = None
    if args.false_alarms_into is not None:
        base = load_pem(args.false_alarms_into, config.observation)
    passes = 0 if base is not None else args.calibrate
    model = fit_pem(config, args.model, args.work, options, calibration_passes=passes, false_alarms_into=base)
    sightings = sum(map(sum, model.parameters.sightings))
    print(f"pem_model={args.model}")
    print(f"fit_frames={model.fit['frames']}")
    print(f"fit_sightings={sightings}")
    print(f"calibration_passes={model.fit.get('calibration_passes', 0)}")
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Check a PEM; prints its key=value lines, returns 1 when a check fails."""
    from negobs_gym.envs.pem import load_pem, shipped_pem_path
    from negobs_gym.errors import UsageError
    from negobs_gym.eval.pem_check import (
        BrakingCheckConfig,
        PolicyCheckConfig,
        check_braking,
        check_pem,
        check_policy,
    )

    if args.no_courses and not (args.braking_seeds or args.policy):
        raise UsageError("--no-courses needs --braking-seeds N or --policy MODEL (nothing would be checked)")
    config, options = _config(args)
    model_path = args.model if args.model is not None else shipped_pem_path(config.observation)
    model = load_pem(model_path, config.observation)
    results = []
    if not args.no_courses:
        log.info(
            "PEM check: %d fresh courses from seed %d, %d frames -> %s",
            config.seeds,
            config.first_seed,
            config.frames,
            args.out,
        )
        results.append(check_pem(model, config, args.out, options=options))
        log.info("wrote %s/check.txt, summary.json, tables.md, pem_check.png", args.out)
    if args.braking_seeds:
        braking = BrakingCheckConfig(
            seeds=args.braking_seeds,
            scenarios=tuple(args.braking_scenarios),
            overrides=tuple(args.overrides or ()),
        )
        log.info("PEM closed-loop check: braking campaign on %d seeds, detector and PEM", braking.seeds)
        results.append(check_braking(model_path, braking, args.out, options))
        log.info("wrote %s/braking_check.txt, braking_detector/, braking_pem/", args.out)
    if args.policy:
        policy = PolicyCheckConfig(
            policy=args.policy,
            seeds=args.policy_seeds,
            first_seed=args.policy_first_seed,
            env_id=args.policy_env,
            overrides=tuple(args.overrides or ()),
        )
        log.info("PEM closed-loop check: %s on %d seeds, detector and PEM", args.policy, policy.seeds)
        results.append(check_policy(model_path, policy, args.out, options))
        log.info("wrote %s/policy_check.txt, policy_detector/, policy_pem/", args.out)
    passed = True
    for result in results:
        lines = result.lines()
        for line in lines[:-1]:
            print(line)
        passed &= result.passed
    print(f"pem_check={'pass' if passed else 'fail'}")
    return 0 if passed else 1
