"""``negobs eval detection|braking|policy``: the evaluation campaigns of :mod:`negobs_gym.eval`.

Options shared by the three campaigns: ``--seeds``, ``--out DIR``, ``--workers N`` (local
processes), ``--ray [ADDRESS]`` (Ray; without ADDRESS a local instance), ``--resume``, ``--rig`` and
``--config FILE``. The TOML file sets fields of the campaign's config dataclass (top-level keys for
every command, a ``[detection]`` / ``[braking]`` / ``[policy]`` table for one); options given on
the command line win over the file. The braking and policy campaigns change their scenes with
``--set KEY.PATH=VALUE`` (the config's ``overrides``); their options that set a scene field are
each that field's ``--set`` path (their config module's ``SCENE_FIELDS``).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from negobs_gym.cli.common import add_runner_options, add_set_option, positive_float, positive_int
from negobs_gym.errors import ConfigError, MissingDependencyError

log = logging.getLogger("negobs_gym.cli.eval")

COMMANDS = ("detection", "braking", "policy")


def load_toml(path: str | Path, command: str) -> dict[str, Any]:
    """Campaign fields from a TOML file: top-level keys plus the ``[command]`` table (lists -> tuples)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        try:
            import tomli as tomllib
        except ModuleNotFoundError as error:
            raise MissingDependencyError("tomli", "--config on Python 3.10") from error
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ConfigError("config", f"cannot read {path}: {error}") from error
    fields = {k: v for k, v in data.items() if not isinstance(v, dict)}
    section = data.get(command, {})
    if not isinstance(section, dict):
        raise ConfigError("config", f"[{command}] must be a table")
    fields.update(section)
    return {k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()}


def build_config(cls: type, toml_fields: dict[str, Any], cli_fields: dict[str, Any]) -> Any:
    """``cls(**toml, **cli)``: unknown TOML keys and invalid values are a :class:`ConfigError`."""
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(toml_fields) - names)
    if unknown:
        raise ConfigError("config", f"unknown keys {unknown} for {cls.__name__}; known: {sorted(names)}")
    merged = {**toml_fields, **{k: v for k, v in cli_fields.items() if v is not None}}
    try:
        return cls(**merged)
    except TypeError as error:
        raise ConfigError("config", str(error)) from error


def _common(parser: argparse.ArgumentParser, default_out: str) -> None:
    group = parser.add_argument_group("campaign options")
    group.add_argument(
        "--seeds", type=positive_int, default=None, help="episodes (seeds 0..N-1; policy: from --first-seed)"
    )
    group.add_argument("--out", default=default_out, help="output directory (default: %(default)s)")
    add_runner_options(group, "episodes")
    group.add_argument(
        "--rig",
        choices=("roi", "native", "reduced"),
        default=None,
        help="paper N rig: braking default roi (the envs' observation), detection native or reduced",
    )
    group.add_argument("--config", metavar="FILE", default=None, help="TOML file of campaign settings")
    group.add_argument("--no-progress", action="store_true", help="no progress bar")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``eval``: its three campaign commands, ``paths`` and ``video``, which draw and replay a
    policy or braking campaign's drives, and ``compare``, which tests two campaigns seed by seed."""
    parser = subparsers.add_parser(
        "eval",
        help="evaluation campaigns: detection recall (paper N Tables 6/7, Fig. 16), braking, a policy; "
        "paths draws a policy or braking campaign's drives, video replays a policy or braking "
        "campaign's episodes as MP4s, compare tests two campaigns seed by seed",
        description="Evaluation campaigns: detection recall and false alarms, braking at 25 km/h, "
        "a saved policy. Each writes CSVs, a JSON summary, tables and PNGs under --out.",
    )
    commands = parser.add_subparsers(dest="campaign", metavar="CAMPAIGN", required=True)

    det = commands.add_parser(
        "detection",
        help="paper N §4.2: recall by size and distance, false alarms per km, Fig. 16",
        description="Drives seeded courses with paper N's pit mix and writes obstacles.csv, frames.csv, "
        "summary.json, tables.md (Tables 6/7 beside paper N's), fig16.png and recall_heatmap.png.",
    )
    _common(det, "outputs/eval/detection")
    det.add_argument("--frames", type=positive_int, default=None, help="total frames (default 1000)")
    det.add_argument("--no-noise", action="store_true", help="sensor noise off")
    det.add_argument(
        "--detector",
        choices=("default", "paper"),
        default=None,
        help="detector judged: default (NegativeDetectorConfig()) or paper (paper N as published)",
    )
    det.add_argument(
        "--detector-set",
        action="append",
        metavar="PATH=VALUE",
        default=None,
        help="set one detector field on top of --detector, VALUE is TOML "
        "(e.g. hdl64_ground_checks.min_depth_ratio=0.2); repeatable",
    )
    det.add_argument(
        "--worst-frames",
        type=int,
        default=None,
        help="PNGs of the frames with the most fused false alarms (default 3; 0: none)",
    )
    det.set_defaults(handler=run_detection)

    brk = commands.add_parser(
        "braking",
        help="25 km/h braking: scripted drivers / an SB3 model, with and without the safety filter",
        description="Runs every scenario x driver x filter on the seeds; prints stopped_before=<k>/<n> "
        "per configuration and writes braking.csv, summary.json, table.md and two PNGs.",
    )
    _common(brk, "outputs/eval/braking")
    brk.add_argument("--scenarios", default=None, help="comma-separated subset of the scenarios")
    brk.add_argument("--drivers", default=None, help="comma-separated subset of reckless,constant_speed")
    brk.add_argument(
        "--model", default=None, help="a saved SB3 model or a shipped policy's name: adds the driver 'sb3'"
    )
    brk.add_argument("--algo", default=None, help="its stable-baselines3 class (default PPO)")
    brk.add_argument(
        "--tighten-pairs",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="paper N's pairs tightened to the close frames' near edge, as the envs' default "
        "(--set observation.tighten_pairs=true); --no-tighten-pairs: paper N's fusion history",
    )
    brk.add_argument(
        "--scan-every",
        type=positive_int,
        default=None,
        metavar="K",
        help="a LiDAR frame every K control steps, carried between (--set observation.scan_every=K; "
        "default 1: every step)",
    )
    brk.add_argument(
        "--scan-far-from",
        dest="scan_far_from_m",
        type=float,
        default=None,
        metavar="M",
        help="with --scan-every K > 1: the steps between frames cast and detect the grid's part "
        "beyond M metres (--set observation.scan_far_from_m=M; 12 keeps the every-step recall)",
    )
    brk.add_argument(
        "--free-track-steps",
        type=positive_int,
        default=None,
        metavar="N",
        help="the most steps (10 Hz) of a free_track episode (default 150: the 15 s limit); "
        "fewer: a quicker false-veto check",
    )
    add_set_option(brk)
    brk.set_defaults(handler=run_braking)

    pol = commands.add_parser(
        "policy",
        help="a saved SB3 model on an env id: success, entries, collisions, progress, vetoes, cost",
        description="Evaluates MODEL on seeds first_seed..first_seed+N-1 of --env, without and/or with "
        "the safety filter.",
    )
    pol.add_argument("model", metavar="MODEL", help="saved stable-baselines3 model (.zip)")
    _common(pol, "outputs/eval/policy")
    pol.add_argument(
        "--env",
        dest="env_id",
        default=None,
        help="env id, shipped scenario or scenario TOML file (default: the one the model's record "
        "names, a shipped policy's NAME.json or its training folder's train.json, with the record's "
        "--set; else negobs_gym/Braking-v0)",
    )
    pol.add_argument("--algo", default=None, help="stable-baselines3 class (default PPO)")
    pol.add_argument("--filter", choices=("off", "on", "both"), default=None, help="default: both")
    pol.add_argument(
        "--stop-for-positive",
        action="store_true",
        default=None,
        help="the filter also stops for the grid's positive-obstacle cells (rows say filter_positive; "
        "default: as the scene's filter.stop_for_positive says)",
    )
    pol.add_argument(
        "--first-seed",
        type=int,
        default=None,
        help="seeds first_seed.. (default 1000000: unseen in training)",
    )
    pol.add_argument(
        "--source",
        choices=("detector", "oracle", "pem"),
        default=None,
        help="grid source (--set observation.source=SOURCE; default: the env's own)",
    )
    add_set_option(pol)
    pol.set_defaults(handler=run_policy)

    paths = commands.add_parser(
        "paths",
        help="draw a policy or braking campaign's drives over their terrains (PNG per episode)",
        description="Draws episodes of a `negobs eval policy --out DIR` or `negobs eval braking --out "
        "DIR` folder from its paths.csv: the terrain with its obstacles, the path, where the car "
        "ended, the vetoed steps, the missed vetoes and the outcome. Default: the episodes that did "
        "not do their task (no goal; braking: no stop before the obstacle, or a veto on the "
        "obstacle-free track).",
    )
    _add_episode_choice(paths, "draw", "paths", "PNGs")
    paths.add_argument(
        "--zoom",
        dest="zoom_m",
        type=positive_float,
        default=None,
        metavar="M",
        help="draw the square of half-width M metres around where each drive ended "
        "(default: the whole terrain)",
    )
    paths.set_defaults(handler=run_paths)

    video = commands.add_parser(
        "video",
        help="replay a policy or braking campaign's episodes as MP4 videos of the env's frames",
        description="Runs episodes of a `negobs eval policy|braking --out DIR` folder again from the "
        "arguments they ran with (DIR/parts) with the env's frames written to MP4 (the grid, the "
        "returns, the detected and true outlines, the filter's corridor and decisions), and checks "
        "each replay against the campaign's recorded rows: a replay that differs (a changed model "
        "file, package or setting) is an error and leaves no video. Default: the episodes that did "
        "not do their task. Needs "
        'imageio-ffmpeg (pip install "negobs_gym[video]").',
    )
    _add_episode_choice(video, "replay", "videos", "MP4s")
    video.add_argument(
        "--model",
        default=None,
        metavar="PATH",
        help="the model the episodes ran, where it lies now (the campaign records the path it was "
        "given; a saved model moved since); the replay is still checked against the record",
    )
    video.set_defaults(handler=run_videos)

    compare = commands.add_parser(
        "compare",
        help="two policy, braking or detection campaigns or scenario runs (or two groups of one) "
        "episode against episode: rates with 95%% intervals, exact McNemar and Wilcoxon signed-rank "
        "tests; detection: recall differences over the courses",
        description="Pairs the episodes of two `negobs eval policy|braking --out` or `negobs "
        "scenario run --out` folders by seed (braking, scenario: scenario and seed) and compares "
        "each outcome (goal, entries, stops before the obstacle, ...) with the exact McNemar test "
        "and each measure (progress, gaps, braking events) with the Wilcoxon signed-rank test; "
        "prints markdown tables. A side is DIR or DIR:GROUP, GROUP a filter setting of a policy "
        "campaign (nofilter, filter, filter_positive) or a driver/filter of a braking campaign or "
        "scenario run (reckless/filter, ppo_offroad_nav_v1/nofilter). With one side only: its "
        "folder's two groups (a policy campaign run with --filter both). Two `negobs eval "
        "detection --out` folders: Fig. 16 recall per mode and distance on their common courses, "
        "the difference with a 95% interval from resampling the courses.",
    )
    compare.add_argument("a", metavar="A", help="DIR or DIR:GROUP")
    compare.add_argument(
        "b", metavar="B", nargs="?", default=None, help="DIR or DIR:GROUP (default: A's other group)"
    )
    compare.add_argument(
        "--out", default=None, metavar="DIR", help="also write compare.md and compare.json there"
    )
    compare.set_defaults(handler=run_compare)


def _add_episode_choice(parser: argparse.ArgumentParser, verb: str, folder: str, files: str) -> None:
    """The campaign folder and the options that choose its episodes (``negobs eval paths``, ``video``)."""
    parser.add_argument(
        "campaign_dir", metavar="DIR", help="the folder `negobs eval policy|braking --out` wrote"
    )
    parser.add_argument(
        "--episode",
        dest="keys",
        action="append",
        default=[],
        metavar="KEY",
        help="an episode of the campaign's episode column, repeatable (default: those that did not "
        "do their task)",
    )
    parser.add_argument("--all", dest="everything", action="store_true", help="every episode")
    parser.add_argument("--limit", type=positive_int, default=None, help=f"{verb} at most N (in key order)")
    parser.add_argument(
        "--to", dest="to_dir", default=None, help=f"folder for the {files} (default: DIR/{folder})"
    )


def _options(args: argparse.Namespace):
    from negobs_gym.eval.campaign import Backend, RunOptions, import_ray

    if args.ray is not None:
        import_ray()  # fail before any work when ray is missing
    return RunOptions(Backend(workers=args.workers, ray=args.ray), args.resume, not args.no_progress)


def _toml(args: argparse.Namespace) -> dict[str, Any]:
    return load_toml(args.config, args.campaign) if args.config else {}


def with_overrides(
    paths: dict[str, str],
    toml: dict[str, Any],
    cli: dict[str, Any],
    sets: Sequence[str] = (),
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The config fields of the TOML file and of the command line, the options of both that set
    a scene field (``paths``: option -> ``--set`` path, the campaign's ``SCENE_FIELDS``) and the
    assignments ``sets`` joined into one ``overrides``: the file's options, its ``overrides``, the
    command's options, then ``sets``."""
    from negobs_gym.eval.campaign import scene_assignments

    scene_toml = {k: v for k, v in toml.items() if k in paths}
    overrides = (
        *scene_assignments(scene_toml, paths),
        *toml.get("overrides", ()),
        *scene_assignments(cli, paths),
        *sets,
    )
    plain = {k: v for k, v in cli.items() if k not in paths}
    return {k: v for k, v in toml.items() if k not in paths and k != "overrides"}, {
        **plain,
        "overrides": overrides,
    }


def _split(text: str | None) -> tuple[str, ...] | None:
    return None if text is None else tuple(t.strip() for t in text.split(",") if t.strip())


def run_detection(args: argparse.Namespace) -> int:
    """The detection campaign; logs where the tables and figures are."""
    from negobs_gym.eval.detection_campaign import DetectionCampaignConfig, run_detection_campaign

    cli = {
        "seeds": args.seeds,
        "frames": args.frames,
        "rig": args.rig,
        "detector": args.detector,
        "detector_set": None if args.detector_set is None else tuple(args.detector_set),
        "worst_frames": args.worst_frames,
    }
    if args.no_noise:
        cli["sensor_noise"] = False
    config = build_config(DetectionCampaignConfig, _toml(args), cli)
    log.info(
        "detection campaign: %d courses, %d frames, %s rig -> %s",
        config.seeds,
        config.frames,
        config.rig,
        args.out,
    )
    out = run_detection_campaign(config, args.out, _options(args))
    s = out.summary
    rates = s.false_alarm_rates("fused")
    log.info(
        "%d frames, %.3f km; fused false alarms %.3f per frame, %.2f per km (on track %.2f, off %.2f)",
        s.frames,
        s.km,
        rates["per_frame"],
        rates["total_per_km"],
        rates["on_track_per_km"],
        rates["off_track_per_km"],
    )
    for path in (
        out.tables_md,
        out.summary_json,
        out.obstacles_csv,
        out.frames_csv,
        out.fig16_png,
        out.heatmap_png,
    ):
        log.info("wrote %s", path)
    return 0


def braking_config(args: argparse.Namespace) -> Any:
    """The :class:`~negobs_gym.eval.braking_campaign.BrakingCampaignConfig` of ``negobs eval
    braking``'s options and ``--config`` file, the options that set a scene field (``SCENE_FIELDS``) as
    ``--set`` assignments before the command's own ``--set``."""
    from negobs_gym.eval.braking_campaign import SCENE_FIELDS, BrakingCampaignConfig

    cli = {
        "seeds": args.seeds,
        "scenarios": _split(args.scenarios),
        "drivers": _split(args.drivers),
        "model_path": args.model,
        "algo": args.algo,
        "free_track_steps": args.free_track_steps,
        **{name: getattr(args, name) for name in SCENE_FIELDS},
    }
    toml, cli = with_overrides(SCENE_FIELDS, _toml(args), cli, args.overrides)
    return build_config(BrakingCampaignConfig, toml, cli)


def run_braking(args: argparse.Namespace) -> int:
    """The braking campaign; prints ``stopped_before=<k>/<n>`` per configuration."""
    from negobs_gym.eval.braking_campaign import run_braking_campaign, summary_line

    config = braking_config(args)
    out = run_braking_campaign(config, args.out, _options(args))
    for s in out.summaries:
        print(summary_line(s))  # the campaign's result on stdout, one line per configuration
    for path in (
        out.table_md,
        out.summary_json,
        out.csv,
        out.vetoes_csv,
        out.margins_png,
        out.first_veto_png,
        out.veto_errors_png,
    ):
        log.info("wrote %s", path)
    return 0


def run_policy(args: argparse.Namespace) -> int:
    """The policy evaluation; prints one line per filter setting."""
    from negobs_gym.eval.policy_campaign import SCENE_FIELDS, PolicyCampaignConfig, run_policy_campaign
    from negobs_gym.eval.stats import format_interval
    from negobs_gym.eval.vetoes import format_veto_error

    filters = {"off": (False,), "on": (True,), "both": (False, True), None: None}[args.filter]
    if args.source is not None:  # a --set, after the record's: it replaces a source the record set
        args.overrides = [*(args.overrides or ()), f"observation.source={args.source}"]
    cli = {
        "model_path": args.model,
        "seeds": args.seeds,
        "env_id": args.env_id,
        "algo": args.algo,
        "filters": filters,
        "first_seed": args.first_seed,
        "stop_for_positive": args.stop_for_positive,
    }
    if args.rig is not None:
        log.warning("--rig is ignored by 'eval policy': the env id's own config is used")
    from negobs_gym.drivers.zoo import recorded_env
    from negobs_gym.spec import combine_overrides, describe_overrides, env_with_overrides

    toml = _toml(args)
    recorded = recorded_env(args.model)
    if recorded is not None and args.env_id is None and "env_id" not in toml:
        cli["env_id"] = recorded[0]  # the env the model was fitted on, with its settings first
        args.overrides = combine_overrides(recorded[1], args.overrides)
        log.info("--env from %s's record: %s", args.model, describe_overrides(*recorded))
    elif recorded is not None and not set(recorded[1]) <= set(args.overrides):
        log.warning(
            "%s was fitted with --set %s; evaluating with %s",
            args.model,
            " --set ".join(recorded[1]),
            " ".join(f"--set {s}" for s in args.overrides) or "no --set",
        )
    toml, cli = with_overrides(SCENE_FIELDS, toml, cli)  # --source: observation.source
    config = build_config(PolicyCampaignConfig, toml, cli)
    if recorded is None and args.env_id is None and "env_id" not in toml:
        log.warning(
            "%s has no record of the env it was fitted on: evaluating on %s", args.model, config.env_id
        )
    label = describe_overrides(config.env_id, args.overrides)  # result lines name the id and settings
    if args.overrides:
        env = env_with_overrides(config.env_id, args.overrides, args.out, replace=not args.resume)
        log.info("--set: %s runs as %s", label, env)
        config = dataclasses.replace(config, env_id=env)
    csv, summary_json, summary = run_policy_campaign(config, args.out, _options(args))
    for name, s in summary.items():
        print(
            f"{label}/{name} success={int(s['successes'])}/{int(s['episodes'])} "
            f"success_interval={format_interval(s['success_interval'])} "
            f"goal={int(s['goals'])}/{int(s['episodes'])} "
            f"goal_interval={format_interval(s['goal_interval'])} "
            f"entries={int(s['entries'])} entry_interval={format_interval(s['entry_interval'])} "
            f"collisions={int(s['collisions'])} "
            f"left_track={int(s['left_track'])} stopped={int(s['stopped'])} "
            f"mean_progress_m={s['mean_progress_m']:.2f} "
            f"vetoes={int(s['vetoes'])} steered={int(s['steered_steps'])} "
            f"vetoes_per_km={s['vetoes_per_km']:.1f} veto_events={int(s['veto_events'])} "
            f"veto_events_per_km={s['veto_events_per_km']:.1f} false_vetoes={int(s['false_vetoes'])} "
            f"missed_vetoes={int(s['missed_vetoes'])} "
            f"veto_error_m={format_veto_error(s['max_veto_error_m'])} "
            f"median_veto_error_m={format_veto_error(s['median_veto_error_m'])} "
            f"median_onset_veto_error_m={format_veto_error(s['median_onset_veto_error_m'])} "
            f"cost={s['cost']:.1f} "
            f"off_track_share={s['off_track_share']:.3f}"
        )
    log.info("wrote %s and %s", csv, summary_json)
    return 0


def run_paths(args: argparse.Namespace) -> int:
    """Draw the chosen episodes; logs each PNG."""
    from negobs_gym.eval.paths import draw_paths

    written = draw_paths(args.campaign_dir, args.keys, zoom_m=args.zoom_m, **_choice(args))
    return _report(written, "draw", args.campaign_dir)


def run_videos(args: argparse.Namespace) -> int:
    """Replay the chosen episodes into videos; prints each MP4."""
    from negobs_gym.eval.replay import replay_videos

    written = replay_videos(args.campaign_dir, args.keys, model=args.model, **_choice(args))
    return _report(written, "replay", args.campaign_dir)


def run_compare(args: argparse.Namespace) -> int:
    """Compare two campaign sides; prints the tables."""
    from negobs_gym.eval.compare import (
        compare_campaigns,
        compare_detection_campaigns,
        is_detection_folder,
        load_sides,
        write_comparison,
    )

    if is_detection_folder(args.a):
        if args.b is None:
            raise ConfigError("B", "a detection campaign is compared with another one: name both folders")
        comparison = compare_detection_campaigns(args.a, args.b)
    else:
        comparison = compare_campaigns(*load_sides(args.a, args.b))
    print(comparison.markdown(), end="", flush=True)  # before the log line on a shared terminal
    if args.out is not None:
        log.info("wrote %s and %s", *write_comparison(comparison, args.out))
    return 0


def _choice(args: argparse.Namespace) -> dict[str, Any]:
    """The options of :func:`_add_episode_choice` besides the folder and keys, as keyword arguments."""
    return {"everything": args.everything, "limit": args.limit, "out_dir": args.to_dir}


def _report(written: list[Path], verb: str, campaign_dir: str) -> int:
    """Print the files written; warn when the default choice found no failed episode."""
    for path in written:
        print(path)
    if not written:
        log.warning(
            "no episode to %s in %s (every episode did its task; --all takes all)", verb, campaign_dir
        )
    return 0
