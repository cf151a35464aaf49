"""Warm start: behaviour cloning of a scripted driver before reinforcement learning.

PPO from a random Gaussian policy first has to learn to drive along the route at all: on
OffroadNav-v1 its training return fell from +6 to -50 over the first 16 k steps
(docs/notebook/training.md, "from scratch"). The route follower is a solved problem, the
pure-pursuit driver, so :func:`warm_start` first fits the policy's action mean to that driver's
actions (DART-style: the executed action carries Gaussian noise so the demonstrations also show
how to return to the route, while the labels are the driver's clean actions; Laskey et al. 2017),
then sets the policy's action standard deviation to ``action_std`` for PPO's exploration. PPO then
learns what the driver cannot do: leave the route around obstacles.

On OffroadTrack-v0, where leaving the track ends the episode, the demonstrator is the
:class:`~negobs_gym.drivers.track_planner.TrackPlannerDriver` instead: it reads the course's
ground-truth obstacles and passes them on the track, which the policy then has to learn from its
grid (``WarmStartConfig.driver``; docs/training.md).

Two options make a fit carry to courses it never saw (``WarmStartConfig``): ``mirror`` also fits
each step's left-right mirror image (:meth:`Demonstrations.mirrored`), and ``hold_out_every`` scores
every K-th demonstration episode instead of fitting it and keeps the epoch that scores best.

The demonstrations come from the training env itself (same observation wrapper, source and
filter), on seeds of their own (``seed + DEMO_SEED_OFFSET + k``), so neither the training seeds
nor the evaluation seeds are reused.
"""

from __future__ import annotations

import copy
import functools
import io
import math
import multiprocessing
import multiprocessing.util
import pickle
import zipfile
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from negobs_gym.core.files import write_bytes_atomic
from negobs_gym.drivers import Driver, make_driver
from negobs_gym.envs.observation import mirror_signs
from negobs_gym.errors import ConfigError, require
from negobs_gym.policies.config import DEMONSTRATORS, STEERING, WarmStartConfig
from negobs_gym.policies.modes import SteeringModesPolicy
from negobs_gym.policies.threads import torch_threads
from negobs_gym.safety import SafetyFilterConfig
from negobs_gym.sim.types import Terrain
from negobs_gym.spec.observation import ObservationConfig

__all__ = [
    "DEMO_SEED_OFFSET",
    "DemonstrationPool",
    "Demonstrations",
    "FitResult",
    "PolicyActor",
    "collect_demonstrations",
    "demonstrator",
    "warm_start",
]

#: Demonstration episodes use seeds ``seed + DEMO_SEED_OFFSET + k`` (training envs use ``seed + i``,
#: evaluations 900,000 on by default).
DEMO_SEED_OFFSET = 500_000
#: Sign of (throttle, steering) in a mirror image: steering changes side.
MIRROR_ACTION_SIGNS = np.array([1.0, -1.0], np.float32)
#: Second word of each episode's noise seed ``[seed + DEMO_SEED_OFFSET + k, NOISE_STREAM]``.
NOISE_STREAM = 1


@dataclass(frozen=True)
class Demonstrations:
    """Observations (the wrapped env's dict, stacked) and the driver's clean actions (N, 2).

    Attributes:
        observations: Each observation key stacked over the N steps.
        actions: The driver's labels (N, 2): throttle/brake, steering.
        episodes: Episodes driven to collect them (a mirrored copy drove none).
        episode_ids: (N,) the demonstration episode ``k`` of each step (its seed is
            ``seed + DEMO_SEED_OFFSET + k``); held-out sets are drawn by episode.
        grid_shape: (channels, rows, cols) of the env's grid, to mirror a flattened one.
        state_signs: (S,) sign of each ``state`` value in a mirror image
            (:func:`~negobs_gym.envs.observation.mirror_signs`).
        grid_max: The largest grid value (``ObservationConfig.grid_max``: 1, or a counting
            grid's ``downsample**2``); files written before it existed hold 0/1 grids.
    """

    observations: dict[str, np.ndarray]
    actions: np.ndarray
    episodes: int
    episode_ids: np.ndarray
    grid_shape: tuple[int, int, int]
    state_signs: np.ndarray
    grid_max: int = 1

    def __add__(self, other: Demonstrations) -> Demonstrations:
        """Both sets, this one's first (DAgger's aggregate)."""
        if (
            other.grid_shape != self.grid_shape
            or other.grid_max != self.grid_max
            or not np.array_equal(other.state_signs, self.state_signs)
        ):
            raise ConfigError(
                "demonstrations",
                f"different observation layouts cannot be joined: grid {self.grid_shape} (max "
                f"{self.grid_max}) vs {other.grid_shape} (max {other.grid_max})"
                + ("" if np.array_equal(other.state_signs, self.state_signs) else ", other state signs"),
            )
        observations = {k: np.concatenate([v, other.observations[k]]) for k, v in self.observations.items()}
        return replace(
            self,
            observations=observations,
            actions=np.concatenate([self.actions, other.actions]),
            episodes=self.episodes + other.episodes,
            episode_ids=np.concatenate([self.episode_ids, other.episode_ids]),
        )

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` as a compressed ``.npz``, atomically (``negobs train`` keeps every
        warm start's labelled steps in ``OUT/demonstrations.npz``)."""
        arrays = {f"obs_{key}": value for key, value in self.observations.items()}
        buffer = io.BytesIO()
        np.savez_compressed(
            buffer,
            actions=self.actions,
            episodes=np.int64(self.episodes),
            episode_ids=self.episode_ids,
            grid_shape=np.asarray(self.grid_shape, dtype=np.int64),
            state_signs=self.state_signs,
            grid_max=np.int64(self.grid_max),
            **arrays,
        )
        return write_bytes_atomic(path, buffer.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> Demonstrations:
        """Demonstrations written by :meth:`save`.

        Raises:
            ConfigError: ``path`` is missing or not such a file.
        """
        try:
            with np.load(path) as data:
                arrays = {key: data[key] for key in data.files}
        except (OSError, ValueError, zipfile.BadZipFile) as error:
            raise ConfigError("demonstrations", f"cannot read {path}: {error}") from error
        missing = [
            k for k in ("actions", "episodes", "episode_ids", "grid_shape", "state_signs") if k not in arrays
        ]
        observations = {key[4:]: value for key, value in arrays.items() if key.startswith("obs_")}
        if missing or not observations:
            raise ConfigError(
                "demonstrations", f"{path} is not a demonstrations file (no {missing or 'obs_*'})"
            )
        return cls(
            observations,
            arrays["actions"],
            int(arrays["episodes"]),
            arrays["episode_ids"],
            tuple(int(v) for v in arrays["grid_shape"]),  # type: ignore[arg-type]
            arrays["state_signs"],
            int(arrays.get("grid_max", 1)),
        )

    def mirrored(self) -> Demonstrations:
        """The same steps seen in a mirror about the vehicle's heading line: grid columns reversed,
        lateral state values and the steering label negated. The car and the rules are left-right
        symmetric, so each mirrored step is a state the driver could meet with its mirrored label."""
        observations = dict(self.observations)
        if "grid" in observations:
            grid = observations["grid"]
            flipped = grid.reshape(len(grid), *self.grid_shape)[..., ::-1]
            observations["grid"] = np.ascontiguousarray(flipped).reshape(grid.shape)
        observations["state"] = (self.observations["state"] * self.state_signs).astype(
            self.observations["state"].dtype
        )
        actions = (self.actions * MIRROR_ACTION_SIGNS).astype(self.actions.dtype)
        return replace(self, observations=observations, actions=actions, episodes=0)


@dataclass(frozen=True)
class FitResult:
    """What :func:`warm_start` did: the mean loss of each epoch on the fitted steps (the head's
    fitted loss) and, with a hold-out, on the held-out ones (the action mean's squared error);
    ``best_epoch`` (0-based) is the epoch whose weights the policy keeps (the lowest held-out
    loss; without a hold-out, the last)."""

    losses: list[float]
    held_out_losses: list[float]
    best_epoch: int


def demonstrator(
    name: str,
    terrain: Terrain,
    planner_sight_m: float = 0.0,
    planner_horizon_m: float = 0.0,
    observation: ObservationConfig | None = None,
    settings: Mapping[str, Any] | None = None,
    safety_filter: SafetyFilterConfig | None = None,
    control_period_s: float = 0.1,
) -> Driver:
    """The scripted driver ``name`` (one of :data:`~negobs_gym.policies.config.DEMONSTRATORS`) for
    one course, with the driver's own defaults (pure pursuit on the centre line; the track planner
    sees ``planner_sight_m`` ahead, 0: the whole course; with ``planner_horizon_m`` > 0 it plans
    again at every step that far ahead; the grid planner plans on the env's grid, laid out as
    ``observation`` says, and with ``filter_lead_s`` keeps to the Eq. 18 of ``safety_filter`` at
    ``control_period_s``), its config then changed by ``settings``
    (:attr:`~negobs_gym.policies.config.WarmStartConfig.driver_settings`)."""
    if name not in DEMONSTRATORS:
        raise ConfigError("driver", f"unknown demonstrator {name!r}; expected one of {DEMONSTRATORS}")
    return make_driver(
        name,
        terrain,
        planner_sight_m=planner_sight_m,
        planner_horizon_m=planner_horizon_m,
        observation=observation,
        settings=settings,
        safety_filter=safety_filter,
        control_period_s=control_period_s,
    )


def collect_demonstrations(
    env: Any,
    steps: int,
    noise_std: float,
    seed: int,
    driver: str = "pure_pursuit",
    policy: Callable[[dict[str, np.ndarray]], np.ndarray] | None = None,
    first_episode: int = 0,
    planner_sight_m: float = 0.0,
    planner_horizon_m: float = 0.0,
    *,
    driver_settings: Mapping[str, Any] | None = None,
    pool: DemonstrationPool | None = None,
) -> Demonstrations:
    """``steps`` steps on ``env`` (a negobs env, possibly wrapped), labelled by the scripted ``driver``.

    Episodes reset on termination or truncation, each on seed ``seed + DEMO_SEED_OFFSET + k`` for
    k = ``first_episode``, ``first_episode + 1``, ...; the executed action is the driver's, or with
    ``policy`` that policy's (DAgger: the learner drives, the driver labels the states it visits),
    plus ``N(0, noise_std)`` noise from a generator of episode k's own, clipped to [-1, 1]. The
    last episode is cut at ``steps``.

    With a ``pool`` (:class:`DemonstrationPool`), the episodes run in its processes, each on its
    own env (``env`` only gives the observation layout) with its own copy of ``policy``, which
    must then pickle (:class:`PolicyActor`). Each episode depends on its number alone, so the steps
    are the same as one process collects, in the same order. Torch acts on one thread either way (a
    result that differs in its last bit can turn a drive into another episode).
    """
    require(isinstance(steps, int) and steps >= 1, "steps", f"must be an int >= 1, got {steps!r}")
    expert = functools.partial(
        demonstrator,
        driver,
        planner_sight_m=planner_sight_m,
        planner_horizon_m=planner_horizon_m,
        settings=driver_settings,
    )
    if pool is not None:
        parts = pool.episodes(expert, policy, first_episode, steps, noise_std, seed)
    else:
        parts = []
        collected = 0
        with torch_threads(1):  # as in a worker, so both act with the same arithmetic
            while collected < steps:
                episode, left = first_episode + len(parts), steps - collected
                parts.append(_demonstrate_episode(env, expert, policy, episode, left, noise_std, seed))
                collected += len(parts[-1].actions)
    return _join(parts, steps, first_episode, env.unwrapped.scenario.observation)


class PolicyActor:
    """A picklable learner for :func:`collect_demonstrations`: the SB3 policy's deterministic
    action. A worker process gets the policy's class, constructor arguments and weights (what
    SB3's ``BasePolicy.save`` keeps), not the model, its envs or its autograd state."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.policy.predict(obs, deterministic=True)[0]

    def __getstate__(self) -> dict[str, Any]:
        # the constructor's lr_schedule is a bound method of the policy; acting needs none
        arguments = {**self.policy._get_constructor_parameters(), "lr_schedule": _no_schedule}
        return {"cls": type(self.policy), "arguments": arguments, "weights": self.policy.state_dict()}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.policy = state["cls"](**state["arguments"])
        self.policy.load_state_dict(state["weights"])
        self.policy.set_training_mode(False)


def _no_schedule(_progress: float) -> float:
    return 0.0


@dataclass(frozen=True)
class _Episode:
    """One demonstration episode's observations (stacked per key) and labels."""

    observations: dict[str, np.ndarray]
    actions: np.ndarray


def _demonstrate_episode(
    env: Any,
    expert: Callable[[Terrain], Driver],
    policy: Callable[[dict[str, np.ndarray]], np.ndarray] | None,
    episode: int,
    max_steps: int,
    noise_std: float,
    seed: int,
) -> _Episode:
    """Demonstration episode ``episode``, at most ``max_steps`` steps: a function of its number alone."""
    course_seed = seed + DEMO_SEED_OFFSET + episode
    # the noise draws a stream of its own: gymnasium seeds the env's np_random from course_seed
    rng = np.random.default_rng([course_seed, NOISE_STREAM])
    obs, info = env.reset(seed=course_seed)
    spec = env.unwrapped.scenario
    driver = expert(
        env.unwrapped.terrain,
        observation=spec.observation,
        safety_filter=spec.filter,
        control_period_s=1.0 / spec.episode.control_hz,
    )
    observations: dict[str, list[np.ndarray]] = {key: [] for key in obs}
    actions: list[np.ndarray] = []
    while len(actions) < max_steps:
        label = driver.act(obs, info)
        for key, value in obs.items():
            observations[key].append(np.array(value, copy=True))
        actions.append(label)
        action = label if policy is None else np.asarray(policy(obs), dtype=np.float64)
        executed = np.clip(action + rng.normal(0.0, noise_std, size=2), -1.0, 1.0).astype(np.float32)
        obs, _, terminated, truncated, info = env.step(executed)
        if terminated or truncated:
            break
    return _Episode({key: np.stack(values) for key, values in observations.items()}, np.stack(actions))


class DemonstrationPool:
    """``workers`` spawned processes that drive demonstration episodes for
    :func:`collect_demonstrations`, each on its own env from ``env_factory`` (picklable).

    Each process pays for its imports (torch, PyBullet) and its env once, seconds of start-up; a
    warm start with DAgger rounds collects once per round, so it keeps one pool open for all of
    them. What drives travels with each collection's episodes instead (the expert and the
    learner's weights, pickled once per collection and loaded once per process), so a reused
    process acts with the weights of the round that asked. The processes start with the first
    episode; :meth:`close` (or leaving the ``with`` block) stops them, each closing its env.
    """

    def __init__(self, workers: int, env_factory: Callable[[], Any]) -> None:
        require(isinstance(workers, int) and workers >= 1, "workers", f"must be an int >= 1, got {workers!r}")
        self.workers = workers
        context = multiprocessing.get_context("spawn")  # no inherited PyBullet state
        self._executor = ProcessPoolExecutor(
            workers, mp_context=context, initializer=_start_worker, initargs=(env_factory,)
        )

    def __enter__(self) -> DemonstrationPool:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the processes (queued episodes are dropped, running ones finish)."""
        self._executor.shutdown(wait=True, cancel_futures=True)

    def episodes(
        self,
        expert: Callable[[Terrain], Driver],
        policy: Callable[[dict[str, np.ndarray]], np.ndarray] | None,
        first_episode: int,
        steps: int,
        noise_std: float,
        seed: int,
    ) -> list[_Episode]:
        """Episodes first_episode, ... until those in order hold ``steps`` steps; at most
        ``workers - 1`` episodes beyond them are driven and dropped (waited for, so the pool is
        idle when this returns)."""
        actors = pickle.dumps((expert, policy))
        done: dict[int, _Episode] = {}
        pending: dict[Future, int] = {}
        try:
            episode = first_episode
            while _steps_in_order(done, first_episode) < steps:
                while len(pending) < self.workers and sum(len(p.actions) for p in done.values()) < steps:
                    args = (actors, episode, steps, noise_std, seed)
                    pending[self._executor.submit(_worker_episode, *args)] = episode
                    episode += 1
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in finished:
                    done[pending.pop(future)] = future.result()
        finally:
            for future in pending:
                future.cancel()
            wait(pending)
        return [done[k] for k in sorted(done)]


#: Per-process state of a demonstration worker: its env and the last collection's actors.
_worker: dict[str, Any] = {}


def _start_worker(env_factory: Callable[[], Any]) -> None:
    torch.set_num_threads(1)  # one process per core; torch's own threads would oversubscribe them
    env = env_factory()
    # closed when the pool shuts the worker down (multiprocessing runs its finalizers at exit)
    multiprocessing.util.Finalize(env, env.close, exitpriority=0)
    _worker.update(env=env)


def _worker_episode(actors: bytes, episode: int, max_steps: int, noise_std: float, seed: int) -> _Episode:
    """One episode in a worker; ``actors`` is the asking collection's pickled (expert, policy),
    unpickled when it differs from the last one this process saw (once per collection)."""
    if _worker.get("actors") != actors:
        _worker.update(actors=actors, expert_policy=pickle.loads(actors))
    expert, policy = _worker["expert_policy"]
    return _demonstrate_episode(_worker["env"], expert, policy, episode, max_steps, noise_std, seed)


def _steps_in_order(done: dict[int, _Episode], first_episode: int) -> int:
    """Steps in the episodes first_episode, first_episode + 1, ... finished without a gap."""
    total, episode = 0, first_episode
    while episode in done:
        total, episode = total + len(done[episode].actions), episode + 1
    return total


def _join(parts: list[_Episode], steps: int, first_episode: int, layout: Any) -> Demonstrations:
    """The episodes in order, cut at ``steps`` steps."""
    lengths = np.cumsum([len(p.actions) for p in parts])
    kept = int(np.searchsorted(lengths, steps)) + 1  # episodes holding the first ``steps`` steps
    parts = parts[:kept]
    episode_ids = np.concatenate([np.full(len(p.actions), first_episode + i) for i, p in enumerate(parts)])
    return Demonstrations(
        {key: np.concatenate([p.observations[key] for p in parts])[:steps] for key in parts[0].observations},
        np.concatenate([p.actions for p in parts])[:steps],
        len(parts),
        episode_ids[:steps].astype(np.int64),
        layout.shape,
        mirror_signs(layout),
        layout.grid_max,
    )


def warm_start(model: Any, demos: Demonstrations, config: WarmStartConfig, seed: int = 0) -> FitResult:
    """Fit ``model.policy``'s action mean to ``demos`` (mean squared error), then set its action std.

    A :class:`~negobs_gym.policies.modes.SteeringModesPolicy` is fitted with its own
    :meth:`~negobs_gym.policies.modes.SteeringModesPolicy.imitation_loss` (the losses of the
    result are that loss); its held-out loss is still the squared error of the action it drives,
    comparable with a single-mean policy's.

    With ``config.mirror`` the fit also sees every step's mirror image. Steps whose steering label
    exceeds ``config.strong_steer`` in magnitude (the passes) enter each epoch
    ``config.strong_steer_repeats`` times, which weights their squared error that much; the
    held-out loss counts every step once. With ``config.hold_out_every`` = K, the steps of every
    K-th episode (``episode_ids % K == K - 1``, and their mirror images) are left out of the fit
    and scored after each epoch; the policy keeps the weights of the epoch where that held-out loss
    was lowest (early stopping). Works on SB3 policies with a diagonal Gaussian head and
    ``log_std`` (PPO, A2C).

    Raises:
        ConfigError: the policy has no ``log_std`` (SAC's squashed policy is not supported), or the
            hold-out leaves no episode to fit or none to score.
    """
    policy = model.policy
    if not hasattr(policy, "log_std"):
        raise ConfigError(
            "algo", f"warm start needs a Gaussian policy with log_std (PPO), got {type(policy).__name__}"
        )
    k = config.hold_out_every
    held = demos.episode_ids % k == k - 1 if k else np.zeros(len(demos.actions), dtype=bool)
    if k and (held.all() or not held.any()):
        raise ConfigError(
            "hold_out_every",
            f"{k} holds out every {k}-th demonstration episode, which leaves "
            f"{'nothing to fit' if held.all() else 'none held out'} among the "
            f"{len(np.unique(demos.episode_ids))} episodes collected: collect more episodes "
            "(more steps) or lower it",
        )
    data = demos + demos.mirrored() if config.mirror else demos
    held = np.concatenate([held, held]) if config.mirror else held
    obs_tensor, _ = policy.obs_to_tensor(data.observations)
    target = torch.as_tensor(data.actions, dtype=torch.float32)
    strong = np.abs(data.actions[:, STEERING]) > config.strong_steer
    fit_idx = torch.as_tensor(
        np.repeat(np.flatnonzero(~held), np.where(strong, config.strong_steer_repeats, 1)[~held])
    )
    held_idx = torch.as_tensor(np.flatnonzero(held))
    params = [
        p for name, p in policy.named_parameters() if name != "log_std" and not name.startswith("value_net")
    ]
    optimiser = torch.optim.AdamW(params, lr=config.learning_rate, weight_decay=config.weight_decay)
    generator = torch.Generator().manual_seed(seed)
    losses: list[float] = []
    held_out_losses: list[float] = []
    best_state, best_epoch = None, config.epochs - 1
    for epoch in range(config.epochs):
        policy.set_training_mode(True)
        order = fit_idx[torch.randperm(len(fit_idx), generator=generator)]
        total = 0.0
        for start in range(0, len(order), config.batch_size):
            idx = order[start : start + config.batch_size]
            loss = _fit_loss(policy, obs_tensor, target, idx)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(idx)
        losses.append(total / len(order))
        if len(held_idx):
            policy.set_training_mode(False)
            with torch.no_grad():
                total = sum(
                    _action_loss(policy, obs_tensor, target, idx).item() * len(idx)
                    for idx in torch.split(held_idx, config.batch_size)
                )
            held_out_losses.append(total / len(held_idx))
            if held_out_losses[-1] == min(held_out_losses):
                best_state, best_epoch = copy.deepcopy(policy.state_dict()), epoch
    if best_state is not None:
        policy.load_state_dict(best_state)
    policy.set_training_mode(False)
    with torch.no_grad():
        policy.log_std.fill_(math.log(config.action_std))
    return FitResult(losses, held_out_losses, best_epoch)


def _fit_loss(policy: Any, obs_tensor: dict[str, torch.Tensor], target: torch.Tensor, idx: torch.Tensor):
    """The fitted loss on the steps ``idx``: a candidates head's own, else the action mean's
    squared error."""
    if isinstance(policy, SteeringModesPolicy):
        return policy.imitation_loss({key: value[idx] for key, value in obs_tensor.items()}, target[idx])
    return _action_loss(policy, obs_tensor, target, idx)


def _action_loss(policy: Any, obs_tensor: dict[str, torch.Tensor], target: torch.Tensor, idx: torch.Tensor):
    """Mean squared error of the policy's action mean on the steps ``idx``."""
    batch = {key: value[idx] for key, value in obs_tensor.items()}
    mean = policy.get_distribution(batch).distribution.mean
    return torch.nn.functional.mse_loss(mean, target[idx])
