"""``negobs scenario``: list, show, run and render scenario specs (see :mod:`negobs_gym.scenarios`).

``run`` prints one result line per seed and exits with 1 when any seed fails a criterion named in
the spec's ``[criteria]``; ``render`` writes the first frame of an episode to a PNG, atomically.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from negobs_gym.cli.common import add_set_option, non_negative_int, positive_float, positive_int
from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import ALGORITHMS

if TYPE_CHECKING:
    from negobs_gym.spec import ScenarioSpec

DRIVER_CHOICES = (
    "reckless",
    "constant_speed",
    "pure_pursuit",
    "track_planner",
    "creeping",
    "grid_planner",
)  # negobs_gym.eval.scenario_runner.DRIVERS, spelt here so that --help imports no simulator


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``scenario`` command and its ``list``, ``show``, ``run`` and ``render`` subcommands."""
    parser = subparsers.add_parser(
        "scenario",
        help="list, show, run or render scenario specs (TOML)",
        description="Scenario specs: the TOML scenes shipped with negobs_gym (paper N and paper T "
        "scenes, the registered envs) or your own TOML files.",
    )
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)

    p_list = sub.add_parser("list", help="names and descriptions of the shipped scenarios")
    p_list.set_defaults(handler=_list)

    p_show = sub.add_parser("show", help="print a scenario as complete TOML (every default filled in)")
    p_show.add_argument("spec", metavar="SPEC", help="shipped scenario name or TOML file")
    add_set_option(p_show)
    p_show.set_defaults(handler=_show)

    p_run = sub.add_parser(
        "run",
        help="run scenarios with a scripted driver or a trained policy; one line per seed; exit 1 if "
        "a criterion fails",
        description="Runs each SPEC once per seed, one after the other, and prints a result line "
        "each. Exits 1 when a seed fails a criterion named in its spec's [criteria], 0 when all pass.",
    )
    p_run.add_argument(
        "specs", nargs="+", metavar="SPEC", help="shipped scenario names or TOML files (a suite: several)"
    )
    pilot = p_run.add_mutually_exclusive_group()
    pilot.add_argument(
        "--driver",
        choices=DRIVER_CHOICES,
        help="scripted driver (default: the spec's run.policy when set, else its run.driver)",
    )
    pilot.add_argument(
        "--policy",
        metavar="MODEL",
        help="a trained policy drives: a saved stable-baselines3 model or a shipped policy's name "
        "(negobs policy list); run.policy",
    )
    p_run.add_argument(
        "--algo",
        choices=ALGORITHMS,
        default=None,
        help="the algorithm that saved --policy's model (default: the spec's run.policy_algo, PPO)",
    )
    filt = p_run.add_mutually_exclusive_group()
    filt.add_argument(
        "--filter", dest="filter", action="store_true", default=None, help="guard with the safety filter"
    )
    filt.add_argument("--no-filter", dest="filter", action="store_false", help="no safety filter")
    p_run.add_argument(
        "--stop-for-positive",
        action="store_true",
        help="the filter also stops for the grid's positive-obstacle cells (filter.stop_for_positive)",
    )
    p_run.add_argument("--seeds", type=positive_int, default=1, help="number of seeds (default: %(default)s)")
    p_run.add_argument("--seed", type=non_negative_int, default=0, help="first seed (default: %(default)s)")
    p_run.add_argument(
        "--workers",
        type=positive_int,
        default=1,
        help="run the seeds in this many processes; lines still come in seed order (default: %(default)s)",
    )
    p_run.add_argument(
        "--draw",
        metavar="DIR",
        default=None,
        help="write each seed's drive over its terrain to DIR/<scenario>_seed<k>.png (path, end pose, "
        "vetoed steps, missed vetoes, verdict)",
    )
    p_run.add_argument(
        "--zoom",
        dest="zoom_m",
        type=positive_float,
        default=None,
        metavar="M",
        help="with --draw: the square of half-width M metres around where the drive ended "
        "(default: the whole terrain)",
    )
    p_run.add_argument(
        "--video",
        metavar="DIR",
        default=None,
        help="write each seed's episode to DIR/<scenario>_seed<k>.mp4: the env's frames at the "
        "control rate, with the filter's corridor and decision (needs imageio-ffmpeg: "
        'pip install "negobs_gym[video]")',
    )
    p_run.add_argument(
        "--out",
        metavar="DIR",
        default=None,
        help="also write the run's tables into DIR (DIR/<scenario> each with several SPECs): "
        "results.csv (a row per seed), vetoes.csv (each veto and missed veto, judged on the ground "
        "truth), paths.csv and scenario.toml (the spec as run; files already there are replaced)",
    )
    add_set_option(p_run)
    p_run.set_defaults(handler=_run)

    p_render = sub.add_parser("render", help="write an episode's first top-down frame to a PNG")
    p_render.add_argument("spec", metavar="SPEC", help="shipped scenario name or TOML file")
    p_render.add_argument("--out", default="outputs/scenario.png", help="PNG to write (default: %(default)s)")
    p_render.add_argument(
        "--seed", type=non_negative_int, default=0, help="episode seed (default: %(default)s)"
    )
    add_set_option(p_render)
    p_render.set_defaults(handler=_render)


def _list(args: argparse.Namespace) -> int:
    from negobs_gym.spec import load_scenario, scenario_names

    for name in scenario_names():
        print(f"{name:28s} {load_scenario(name).description}", file=sys.stdout)
    return 0


def _show(args: argparse.Namespace) -> int:
    from negobs_gym.spec import spec_to_toml

    sys.stdout.write(spec_to_toml(_spec(args)))
    return 0


def _spec(args: argparse.Namespace, name: str | None = None) -> ScenarioSpec:
    """The scenario ``name`` (default: the SPEC argument) with the ``--set`` changes."""
    from negobs_gym.spec import load_scenario
    from negobs_gym.spec.overrides import apply_overrides

    return apply_overrides(load_scenario(args.spec if name is None else name), args.overrides)


def _run(args: argparse.Namespace) -> int:
    from negobs_gym.eval.scenario_runner import run_scenario_seeds
    from negobs_gym.eval.scenario_tables import check_csv_text, write_scenario_tables

    if args.zoom_m is not None and not args.draw:
        raise ConfigError("--zoom", "needs --draw DIR (it sets the drawn window)")
    specs = [_run_spec(args, name) for name in args.specs]  # every spec checked before any episode
    names = [spec.name for spec in specs]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice and (args.out or args.draw or args.video):
        raise ConfigError("SPEC", f"{twice} named twice: their files would share the scenario's name")
    policies = sorted({spec.run.policy for spec in specs} - {""})
    if args.out is not None:
        for field, text in [("name", n) for n in names] + [("run.policy", p) for p in policies]:
            check_csv_text(field, text)
    for spec in specs:
        if spec.run.policy:
            _check_policy(spec)
    log = logging.getLogger("negobs_gym.cli")
    runs, failed = 0, []
    for spec in specs:
        results = []
        for result in run_scenario_seeds(
            spec,
            seeds=range(args.seed, args.seed + args.seeds),
            workers=args.workers,
            draw_dir=args.draw,
            draw_zoom_m=args.zoom_m,
            video_dir=args.video,
        ):
            print(result.line(), file=sys.stdout, flush=True)
            results.append(result)
        runs += len(results)
        failed += [f"{r.scenario} seed={r.seed}" for r in results if not r.passed]
        if args.out is not None:
            out = Path(args.out) if len(specs) == 1 else Path(args.out) / spec.name
            written = write_scenario_tables(out, spec, results)
            log.info("wrote %s", ", ".join(map(str, written)))
    if failed:
        log.warning("%d of %d runs failed a criterion: %s", len(failed), runs, ", ".join(failed))
    else:
        log.info("all %d runs passed", runs)
    return 1 if failed else 0


def _run_spec(args: argparse.Namespace, name: str) -> ScenarioSpec:
    """The scenario ``name`` with ``--set``, ``--driver``, ``--policy``, ``--algo`` and
    ``--filter`` folded into its ``[run]`` table and ``--stop-for-positive`` into its ``[filter]``:
    what ran, as ``scenario.toml`` records it."""
    spec = _spec(args, name)
    changes = {"driver": args.driver, "filter": args.filter, "policy_algo": args.algo}
    if args.driver is not None:
        changes["policy"] = ""  # the scripted driver named drives, not the spec's policy
    if args.policy is not None:
        changes["policy"] = args.policy
    changes = {k: v for k, v in changes.items() if v is not None}
    spec = dataclasses.replace(spec, run=dataclasses.replace(spec.run, **changes))
    if args.stop_for_positive:
        spec = dataclasses.replace(spec, filter=dataclasses.replace(spec.filter, stop_for_positive=True))
    return spec


def _check_policy(spec: ScenarioSpec) -> None:
    """Before the first episode: the spec's policy exists (else a ConfigError naming
    ``run.policy``); the log names the env it was fitted on, and warns when the model was fitted
    with ``--set`` settings that the scenario does not have (a grid it was not fitted on)."""
    from negobs_gym.drivers.zoo import recorded_env, resolve_model
    from negobs_gym.spec import describe_overrides
    from negobs_gym.spec.overrides import apply_overrides

    policy, log = spec.run.policy, logging.getLogger("negobs_gym.cli")
    resolve_model(policy, "run.policy")
    recorded = recorded_env(policy)
    fitted = "no record of the env it was fitted on" if recorded is None else describe_overrides(*recorded)
    log.info("%s drives %s (%s)", policy, spec.name, fitted)
    if recorded is not None and apply_overrides(spec, recorded[1]) != spec:
        settings = " ".join(f"--set {s}" for s in recorded[1])
        log.warning(
            "%s was fitted with %s, which %s lacks: add them to drive it on its own grid",
            policy,
            settings,
            spec.name,
        )


def _render(args: argparse.Namespace) -> int:
    from negobs_gym.envs.base import NegObsEnv
    from negobs_gym.sim.render import write_png_atomic

    env = NegObsEnv(scenario=_spec(args), render_mode="rgb_array")
    try:
        env.reset(seed=args.seed)
        write_png_atomic(env.render(), Path(args.out))
    finally:
        env.close()
    logging.getLogger("negobs_gym.cli").info("wrote %s", args.out)
    return 0
