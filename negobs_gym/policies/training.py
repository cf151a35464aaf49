"""Train a navigation policy on a negobs env: what ``negobs train`` and ``examples/train_ppo.py`` run.

:func:`train` builds ``envs`` copies of the run's env (an env id, a shipped scenario or a TOML
spec, with :data:`~negobs_gym.policies.config.TRAINING_DEFAULTS` and the run's ``overrides``
applied: :func:`training_spec`), each behind the Eq. 18
:class:`~negobs_gym.safety.BrakingSafetyFilter` where that spec's ``run.filter`` says so and always
behind :class:`~negobs_gym.policies.PolicyObservation`; trains PPO or SAC with ``MultiInputPolicy``
and :class:`~negobs_gym.policies.extractor.GridStateExtractor`; logs SB3's CSV (and TensorBoard
when ``tensorboard`` is installed); evaluates on unseen seeds every ``eval_every`` steps into
``eval.csv``; saves checkpoints, and resumes from the latest one.

Output folder::

    model.zip                 final model (loads in ``negobs eval policy``)
    checkpoints/model_<N>.zip every ``checkpoint_every`` env steps
    eval.csv                  one row per evaluation (callbacks.EVAL_COLUMNS)
    logs/<start step>/        SB3 logger: progress.csv (+ TensorBoard events)
    scenario.toml             the scenario the run trains on, every override applied
    train.json                the config, the code (version, git commit), steps done, wall time
                              and steps/s of the last session
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import importlib.util
import json
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import torch

import negobs_gym  # noqa: F401 - registers the env ids (also in vector-env workers)
from negobs_gym.core.files import write_text_atomic
from negobs_gym.drivers.zoo import FITTED_ON, fitted_on_record
from negobs_gym.envs import make_env
from negobs_gym.envs.observation import state_fields
from negobs_gym.errors import ConfigError
from negobs_gym.eval.episode import STANDSTILL_S, EpisodeStop, drive_episode
from negobs_gym.policies.config import TRAINING_DEFAULTS, TrainConfig, config_from_record
from negobs_gym.policies.extractor import GridStateExtractor
from negobs_gym.policies.observation import PolicyDriver, PolicyObservation
from negobs_gym.policies.threads import torch_threads
from negobs_gym.safety.filter import BrakingSafetyFilter, SafetyFilterConfig
from negobs_gym.spec import ScenarioSpec, apply_overrides, describe_overrides, spec_for_env, spec_to_toml
from negobs_gym.spec.overrides import recorded_env_in

log = logging.getLogger(__name__)

__all__ = [
    "TrainResult",
    "filter_setting",
    "make_training_env",
    "run_filter",
    "train",
    "training_overrides",
    "training_spec",
]


@dataclass(frozen=True)
class TrainResult:
    """Where :func:`train` put things and how long it took (this session only when resumed)."""

    model_path: Path
    eval_csv: Path
    steps: int
    wall_s: float
    steps_per_s: float
    last_eval: dict[str, float]


def training_overrides(config: TrainConfig) -> list[str]:
    """The assignments a run applies to its env's scenario: :data:`TRAINING_DEFAULTS`, then its own."""
    return [*TRAINING_DEFAULTS, *config.overrides]


def training_spec(config: TrainConfig) -> ScenarioSpec:
    """The scenario ``config`` trains on: its env's spec with :func:`training_overrides` applied.

    Raises:
        ConfigError: an unknown env, or a bad assignment (its full path).
    """
    return apply_overrides(spec_for_env(config.env), training_overrides(config))


def run_filter(spec: ScenarioSpec) -> SafetyFilterConfig | None:
    """The safety filter a training run's env and evaluation drive behind: ``spec``'s ``[filter]``
    settings, None without ``run.filter``.

    Raises:
        ConfigError: ``filter.stop_for_positive`` without ``run.filter`` (it would do nothing).
    """
    if not spec.run.filter:
        if spec.filter.stop_for_positive:
            raise ConfigError(
                "filter.stop_for_positive",
                "needs the filter: set run.filter=true (negobs train --filter) too",
            )
        return None
    return spec.filter


def make_training_env(env: str, overrides: Sequence[str] = (), grid_input: bool = True) -> gym.Env:
    """One training env: :func:`negobs_gym.envs.make_env` of ``env`` with
    :data:`TRAINING_DEFAULTS` and then ``overrides`` applied, behind the safety filter where the
    resulting spec's ``run.filter`` says so (:func:`run_filter`), and behind
    :class:`PolicyObservation` (the grid dropped when not ``grid_input``)."""
    task = make_env(env, [*TRAINING_DEFAULTS, *overrides])
    settings = run_filter(task.unwrapped.scenario)
    if settings is not None:
        task = BrakingSafetyFilter(task, config=settings)
    return PolicyObservation(task, grid=grid_input)


def filter_setting(config: TrainConfig) -> bool | SafetyFilterConfig:
    """The run's filter, from its spec: False, or the settings it trains and evaluates behind."""
    return run_filter(training_spec(config)) or False


def evaluate(model: Any, config: TrainConfig) -> list[dict[str, Any]]:
    """``config.eval_episodes`` episodes of ``model`` on fresh raw envs, driven by the one episode
    loop as ``negobs eval policy`` drives them: each one's
    :meth:`~negobs_gym.eval.episode.EpisodeResult.metrics`."""
    results = []
    for k in range(config.eval_episodes):
        env = make_env(config.env, training_overrides(config))
        max_steps = env.unwrapped.scenario.episode.max_episode_steps
        driver = PolicyDriver(model)
        guard = filter_setting(config)
        stop = EpisodeStop(max_steps=max_steps, standstill_s=STANDSTILL_S)
        with contextlib.closing(env):
            result = drive_episode(env, driver, seed=config.eval_seed + k, filter=guard, stop=stop)
        results.append(result.metrics())
    return results


def logger_formats() -> list[str]:
    """SB3 logger outputs: CSV always, TensorBoard when the ``tensorboard`` package is installed."""
    if importlib.util.find_spec("tensorboard") is not None:
        return ["csv", "tensorboard"]
    log.info('TensorBoard logs off: pip install "negobs_gym[train]" (tensorboard) to get them')
    return ["csv"]


def _env_factory(config: TrainConfig) -> Callable[[], gym.Env]:
    """A picklable maker of the run's training env, for worker processes."""
    return functools.partial(make_training_env, config.env, config.overrides, config.grid_input)


def _vec_env(config: TrainConfig):
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    thunk = _env_factory(config)
    if config.vec_env == "ray":
        from negobs_gym.policies.ray_envs import RayVecEnv

        vec_cls: Any = functools.partial(RayVecEnv, address=config.ray_address)
    elif config.envs == 1:
        vec_cls = DummyVecEnv
    elif config.vec_env == "prefetch":
        from negobs_gym.envs.vector import PrefetchVecEnv

        vec_cls = PrefetchVecEnv
    elif config.vec_env == "build_ahead":
        from negobs_gym.envs.build_ahead import BuildAheadVecEnv

        vec_cls = BuildAheadVecEnv
    else:
        vec_cls = SubprocVecEnv
    venv = VecMonitor(vec_cls([thunk] * config.envs))
    venv.seed(config.seed)
    return venv


def _policy(
    config: TrainConfig, grid_shape: tuple[int, int, int], state: tuple[str, ...] = ()
) -> tuple[Any, dict[str, Any]]:
    """SB3's policy (class or name) and its keyword arguments: the grid CNN, and the steering head
    (``state``: the names of the state observation's values, where a route-offset head finds its
    route point)."""
    kwargs: dict[str, Any] = {
        "features_extractor_class": GridStateExtractor,
        "features_extractor_kwargs": {"grid_shape": grid_shape, "config": config.extractor},
    }
    if config.head.route_offset_m > 0:
        from negobs_gym.policies.route_offset import RouteOffsetPolicy, route_columns

        columns = route_columns(state, config.head.route_point_m)
        return RouteOffsetPolicy, {**kwargs, "head": config.head, "state_columns": columns}
    if config.head.modes == 1:
        return "MultiInputPolicy", kwargs
    from negobs_gym.policies.modes import SteeringModesPolicy

    return SteeringModesPolicy, {**kwargs, "head": config.head}


def _new_model(
    config: TrainConfig, venv: Any, grid_shape: tuple[int, int, int], state: tuple[str, ...] = ()
) -> Any:
    """A fresh model of ``config``'s algorithm, its weights drawn on ``config.torch_threads``
    threads: torch's orthogonal initialisation (a QR decomposition) gives other weights from the
    same seed on another thread count."""
    import stable_baselines3

    policy, policy_kwargs = _policy(config, grid_shape, state)
    common = {
        "policy_kwargs": policy_kwargs,
        "learning_rate": config.learning_rate,
        "gamma": config.gamma,
        "batch_size": config.batch_size,
        "seed": config.seed,
        "device": "cpu",
        "verbose": 0,
    }
    with torch_threads(config.torch_threads):
        if config.algo == "PPO":
            return stable_baselines3.PPO(
                policy, venv, n_steps=config.n_steps, target_kl=config.target_kl or None, **common
            )
        return stable_baselines3.SAC(policy, venv, buffer_size=config.buffer_size, **common)


#: Settings besides the scenario that must match between a run and the run it resumes.
_RESUME_FIELDS = ("algo", "grid_input", "init_model")


def train(config: TrainConfig, out_dir: str | Path, *, resume: bool = False) -> TrainResult:
    """Train (or resume) as ``config`` says; files under ``out_dir`` (module docstring).

    Every saved zip records the env it was fitted on (:data:`~negobs_gym.drivers.zoo.FITTED_ON`):
    ``config.env`` and ``config.overrides``, which ``negobs eval policy`` applies by default.

    Raises:
        ConfigError: unknown env or bad override; ``resume`` without a checkpoint, or with
            another scenario (any setting, the grid source and the filter included), algorithm,
            policy input or init model; nothing left to train; a new run into a folder that
            holds checkpoints.
    """
    import stable_baselines3
    from stable_baselines3.common.logger import configure

    from negobs_gym.policies.callbacks import (
        CheckpointCallback,
        CriticWarmupCallback,
        EvalCallback,
        ProgressBarCallback,
        latest_checkpoint,
        save_model_atomic,
    )

    out = Path(out_dir)
    probe = _env_factory(config)()  # fails early on a bad env or override
    grid_shape, spec = probe.grid_shape, probe.unwrapped.scenario
    probe.close()
    checkpoint = latest_checkpoint(out / "checkpoints")
    if resume:
        _check_resume(config, spec, out, checkpoint)
    elif checkpoint is not None:  # a later --resume would mix the two runs
        raise ConfigError("out", f"{out} holds checkpoints of an earlier run: use --resume or another --out")
    if not (resume and (out / "scenario.toml").is_file()):  # what the run trains on, for the record
        write_text_atomic(out / "scenario.toml", spec_to_toml(spec))
    venv = _vec_env(config)
    with torch_threads(config.torch_threads), contextlib.closing(venv):
        if checkpoint is not None:
            model = getattr(stable_baselines3, config.algo).load(checkpoint, env=venv, device="cpu")
            warm = _previous_warm_start(out)  # the record of the run this one continues
            log.info("resuming from %s at %d steps", checkpoint, model.num_timesteps)
        elif config.init_model:
            model = _init_model(config, venv)
            warm = {}
        else:
            model = _new_model(config, venv, grid_shape, state_fields(spec.observation))
            warm = _warm_start(model, config, out)
        setattr(model, FITTED_ON, fitted_on_record(config.env, config.overrides))
        if warm and checkpoint is None:  # the cloned policy before any PPO update, for eval
            save_model_atomic(model, out / "warm_start.zip")
        start_step = model.num_timesteps
        if start_step >= config.steps:
            raise ConfigError(
                "steps", f"nothing to train: the checkpoint has {start_step} >= {config.steps} steps"
            )
        code = _code_version()  # the code the run starts on, kept though the checkout may move on
        _write_record(out, config, model.num_timesteps, start_step, code, warm_start=warm)
        model.set_logger(configure(str(out / "logs" / str(start_step)), logger_formats()))
        every = config.eval_every if config.eval_every > 0 else config.steps
        evaluation = EvalCallback(
            functools.partial(evaluate, config=config),
            out / "eval.csv",
            every,
            # the row the fine-tuning or the cloned policy starts from
            at_start=bool(config.init_model or warm) and start_step == 0,
        )
        callbacks = [ProgressBarCallback(config.steps, config.progress), evaluation]
        if config.critic_warmup_steps > 0:
            callbacks.append(CriticWarmupCallback(config.critic_warmup_steps))
        if config.checkpoint_every > 0:
            callbacks.append(CheckpointCallback(out / "checkpoints", config.checkpoint_every))
        begin = time.perf_counter()
        model.learn(config.steps - start_step, callback=callbacks, reset_num_timesteps=False)
        wall_s = time.perf_counter() - begin
    if config.checkpoint_every > 0:  # the end is a checkpoint too: --resume with more --steps goes on from it
        save_model_atomic(model, out / "checkpoints" / f"model_{model.num_timesteps}.zip")
    model_path = save_model_atomic(model, out / "model.zip")
    done = model.num_timesteps - start_step
    result = TrainResult(
        model_path, out / "eval.csv", model.num_timesteps, wall_s, done / wall_s, evaluation.last
    )
    _write_record(
        out,
        config,
        model.num_timesteps,
        start_step,
        code,
        wall_s=wall_s,
        last_eval=evaluation.last,
        warm_start=warm,
    )
    return result


def _init_model(config: TrainConfig, venv: Any) -> Any:
    """``config.init_model``'s weights, with this run's hyperparameters and its step count at 0.

    Raises:
        ConfigError: no such model, or its algorithm or observation space differs (``init_model``).
    """
    import stable_baselines3

    from negobs_gym.drivers.zoo import resolve_model

    path = resolve_model(config.init_model, field="init_model")
    try:
        model = getattr(stable_baselines3, config.algo).load(
            path,
            env=venv,
            device="cpu",
            learning_rate=config.learning_rate,
            n_steps=config.n_steps,
            batch_size=config.batch_size,
            gamma=config.gamma,
            **({"target_kl": config.target_kl or None} if config.algo == "PPO" else {}),
        )
    except (ValueError, TypeError) as error:  # SB3: space mismatch (ValueError), other algorithm (TypeError)
        run = describe_overrides(config.env, config.overrides)
        fit = f"{path} does not fit this run ({config.algo}, {run}, grid input {config.grid_input})"
        raise ConfigError("init_model", f"{fit}: {error}") from error
    model.num_timesteps = 0
    model.set_random_seed(config.seed)
    if config.init_action_std:
        with torch.no_grad():
            model.policy.log_std.fill_(math.log(config.init_action_std))
    log.info("initialised from %s", path)
    return model


def _warm_start(model: Any, config: TrainConfig, out: Path) -> dict[str, Any]:
    """Behaviour-clone a scripted driver into a new PPO model (``config.warm_start``); what
    was done, for ``train.json`` (empty without a warm start). All labelled steps are kept in
    ``out/demonstrations.npz``. With ``workers`` > 1 one pool of processes drives the episodes of
    the first collection and of every DAgger round (they start once)."""
    ws = config.warm_start
    if not ws.enabled:
        return {}
    from negobs_gym.policies.pretrain import (
        DemonstrationPool,
        Demonstrations,
        PolicyActor,
        collect_demonstrations,
        warm_start,
    )

    begin = time.perf_counter()
    env = _env_factory(config)()
    pool = DemonstrationPool(ws.workers, _env_factory(config)) if ws.workers > 1 else None
    collect = functools.partial(
        collect_demonstrations,
        planner_sight_m=ws.planner_sight_m,
        planner_horizon_m=ws.planner_horizon_m,
        driver_settings=ws.driver_settings,
        pool=pool,
    )
    try:
        if ws.demonstrations:
            demos = Demonstrations.load(ws.demonstrations)
            _check_layout(demos, env, ws.demonstrations)
            log.info(
                "warm start from %s: %d steps, %d episodes",
                ws.demonstrations,
                len(demos.actions),
                demos.episodes,
            )
        else:
            demos = collect(env, ws.steps, ws.noise_std, config.seed, ws.driver)
        fit = warm_start(model, demos, ws, config.seed)
        _log_fit(0, ws.dagger_rounds, demos, fit)
        for round_ in range(1, ws.dagger_rounds + 1):
            learner = PolicyActor(model.policy)
            demos += collect(
                env, ws.steps, ws.noise_std, config.seed, ws.driver, learner, first_episode=demos.episodes
            )
            fit = warm_start(model, demos, ws, config.seed)
            _log_fit(round_, ws.dagger_rounds, demos, fit)
    finally:
        if pool is not None:
            pool.close()
        env.close()
    demos.save(out / "demonstrations.npz")
    record = {
        "steps": ws.steps,
        "driver": ws.driver,
        "dagger_rounds": ws.dagger_rounds,
        "planner_sight_m": ws.planner_sight_m,
        "planner_horizon_m": ws.planner_horizon_m,
        "driver_settings": dict(ws.driver_settings),
        "mirror": ws.mirror,
        "hold_out_every": ws.hold_out_every,
        "demonstrations": ws.demonstrations,
        "workers": ws.workers,
        "strong_steer": ws.strong_steer,
        "strong_steer_repeats": ws.strong_steer_repeats,
        "demonstration_steps": len(demos.actions),
        "episodes": demos.episodes,
        "first_loss": fit.losses[0],
        "last_loss": fit.losses[-1],
        "held_out_losses": fit.held_out_losses,
        "best_epoch": fit.best_epoch,
        "wall_s": time.perf_counter() - begin,
    }
    log.info("warm start: %s", record)
    return record


def _check_layout(demos: Any, env: Any, path: str) -> None:
    """Saved demonstrations must have this env's observation: the same keys, grid and state."""
    space = env.observation_space
    layout = env.unwrapped.scenario.observation
    same = (
        set(demos.observations) == set(space.spaces)
        and demos.grid_shape == layout.shape
        and demos.grid_max == layout.grid_max
        and all(demos.observations[k].shape[1:] == space[k].shape for k in space.spaces)
    )
    if not same:
        recorded = {k: v.shape[1:] for k, v in demos.observations.items()}
        wanted = {k: s.shape for k, s in space.spaces.items()}
        raise ConfigError(
            "demonstrations",
            f"{path} holds observations {recorded} (grid {demos.grid_shape}, values up to "
            f"{demos.grid_max}); this env gives {wanted} (grid {layout.shape}, up to {layout.grid_max})",
        )


def _log_fit(round_: int, rounds: int, demos: Any, fit: Any) -> None:
    """One line per fit: a warm start with DAgger runs for half an hour before PPO's first line."""
    held_out = (
        f", held-out {min(fit.held_out_losses):.4f} (epoch {fit.best_epoch + 1} kept)"
        if fit.held_out_losses
        else ""
    )
    log.info(
        "warm start fit %d/%d: %d steps, %d episodes, loss %.4f -> %.4f%s",
        round_,
        rounds,
        len(demos.actions),
        demos.episodes,
        fit.losses[0],
        fit.losses[-1],
        held_out,
    )


def _previous_warm_start(out: Path) -> dict[str, Any]:
    record = out / "train.json"
    return json.loads(record.read_text(encoding="utf-8")).get("warm_start", {}) if record.exists() else {}


def _code_version() -> str:
    from negobs_gym.core.provenance import code_version

    return code_version()


def _write_record(
    out: Path, config: TrainConfig, steps: int, start_step: int, code: str, **session: Any
) -> None:
    """``train.json``: the config, the code the session started on and progress (written at the
    start too, for ``--resume``)."""
    wall_s = session.get("wall_s")
    record = {
        "config": dataclasses.asdict(config),
        "code": code,  # what a shipped policy's record names as its fitted_on code
        "steps": steps,
        "session_start_step": start_step,
        "session_wall_s": wall_s,
        "session_steps_per_s": (steps - start_step) / wall_s if wall_s else None,
        "last_eval": session.get("last_eval", {}),
        "warm_start": session.get("warm_start", {}),
    }
    write_text_atomic(out / "train.json", json.dumps(record, indent=1, sort_keys=True))


def _check_resume(config: TrainConfig, spec: ScenarioSpec, out: Path, checkpoint: Path | None) -> None:
    """A resumed run must train what the run in ``out`` trained: the same scenario once every
    override is applied (so ``--source oracle`` and ``--set observation.source=oracle`` agree),
    algorithm, policy input and init model. Its ``train.json`` may be of an earlier version
    (:func:`~negobs_gym.policies.config.config_from_record`)."""
    if checkpoint is None:
        raise ConfigError("resume", f"no checkpoint under {out / 'checkpoints'} to resume from")
    record = out / "train.json"
    if not record.exists():
        return
    before = config_from_record(json.loads(record.read_text(encoding="utf-8"))["config"])
    env = recorded_env_in(before.env, out)  # an earlier version's --set run trained on OUT/scenario.toml
    before_spec = training_spec(dataclasses.replace(before, env=env))
    differ = {
        f"{k}": (getattr(before, k), getattr(config, k))
        for k in _RESUME_FIELDS
        if getattr(before, k) != getattr(config, k)
    }
    differ.update(_spec_differences(before_spec.to_dict(), spec.to_dict()))
    if differ:
        listed = "; ".join(f"{k}: {old!r} there, {new!r} now" for k, (old, new) in differ.items())
        raise ConfigError("resume", f"this run differs from the run in {out}: {listed}")


def _spec_differences(before: Any, now: Any, path: str = "") -> dict[str, tuple[Any, Any]]:
    """The ``--set`` paths whose values differ between two :meth:`ScenarioSpec.to_dict` tables."""
    if isinstance(before, Mapping) and isinstance(now, Mapping):
        found: dict[str, tuple[Any, Any]] = {}
        for key in sorted(set(before) | set(now), key=str):
            found.update(_spec_differences(before.get(key), now.get(key), f"{path}{key}."))
        return found
    return {} if before == now else {path.rstrip("."): (before, now)}
