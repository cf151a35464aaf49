"""Configs of :mod:`negobs_gym.policies` (no torch here, so the CLI can read the choices cheaply).

Neither paper trains a policy (paper N detects negative obstacles, paper T traversable regions):
no value below comes from them. Each is a choice, with its reason beside it.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping
from dataclasses import InitVar, dataclass, field
from typing import Any

from negobs_gym.errors import ConfigError, require

__all__ = [
    "ALGORITHMS",
    "DEMONSTRATORS",
    "SOURCES",
    "STEERING",
    "TRAINING_DEFAULTS",
    "GridCnnConfig",
    "SteeringHeadConfig",
    "TrainConfig",
    "WarmStartConfig",
    "config_from_record",
    "legacy_settings",
    "source_settings",
    "steering_head",
]

#: stable-baselines3 algorithms ``negobs train`` offers (both take a continuous Box action).
ALGORITHMS: tuple[str, ...] = ("PPO", "SAC")
#: ``negobs train --source``: the scenario's grid source (``observation.source``), or ``state``
#: (:func:`source_settings`).
SOURCES: tuple[str, ...] = ("detector", "oracle", "pem", "state")
#: Scenario settings a training run starts from, before its own ``overrides``: no safety filter,
#: whatever the scene's ``[run]`` table says. That table sets up ``negobs scenario run``'s test,
#: which runs behind the filter by default; a policy trains without it unless its overrides say
#: ``run.filter=true`` (``negobs train --filter``).
TRAINING_DEFAULTS: tuple[str, ...] = ("run.filter=false", "filter.stop_for_positive=false")
#: Vector envs for ``envs > 1`` (``TrainConfig.vec_env``).
VEC_ENVS: tuple[str, ...] = ("build_ahead", "subproc", "prefetch", "ray")
#: Scripted drivers the warm start can clone (``WarmStartConfig.driver``).
DEMONSTRATORS: tuple[str, ...] = ("pure_pursuit", "track_planner", "grid_planner")
#: Column of the steering command in an env action (throttle/brake, steering).
STEERING = 1


@dataclass(frozen=True, kw_only=True)
class GridCnnConfig:
    """Layers of :class:`~negobs_gym.policies.extractor.GridStateExtractor` (papers silent; reasons
    per field).

    Attributes:
        conv_channels: Output channels per conv layer. 16-32-32: the input is 4 binary channels,
            so a few dozen filters suffice, and the network stays fast on 2 CPU cores.
        kernel_sizes: One odd kernel size per layer; 3 x 3 cells (2.4 m at the default 80 cm
            cells) sees a pit next to its neighbours without blurring a one-cell pit away.
        strides: Stride per layer; the first is 1 so a one-cell obstacle still reaches the
            second layer at full resolution, then 2 and 2 take 36 x 16 to 9 x 4 (a 9-cell,
            7.2 m receptive field, most of the 10.5 m Eq. 18 braking distance at 25 km/h).
        grid_features: Width of the linear layer after the convolutions; 128 keeps the
            flattened 1152 conv outputs to ~150 k weights.
    """

    conv_channels: tuple[int, ...] = (16, 32, 32)
    kernel_sizes: tuple[int, ...] = (3, 3, 3)
    strides: tuple[int, ...] = (1, 2, 2)
    grid_features: int = 128

    def __post_init__(self) -> None:
        n = len(self.conv_channels)
        require(n >= 1, "conv_channels", "needs at least one conv layer")
        for name in ("kernel_sizes", "strides"):
            require(len(getattr(self, name)) == n, name, f"needs one value per conv layer ({n})")
        for name in ("conv_channels", "kernel_sizes", "strides"):
            values = getattr(self, name)
            require(
                all(isinstance(v, int) and v >= 1 for v in values), name, f"must be ints >= 1, got {values}"
            )
        require(all(k % 2 == 1 for k in self.kernel_sizes), "kernel_sizes", "must be odd (centred padding)")
        require(self.grid_features >= 1, "grid_features", f"must be >= 1, got {self.grid_features}")


@dataclass(frozen=True, kw_only=True)
class SteeringHeadConfig:
    """The policy's steering head (:mod:`negobs_gym.policies.modes`; the values are choices).

    Attributes:
        modes: Steering candidates the head proposes (1: SB3's single Gaussian mean). With K > 1
            it outputs K steering values and a score for each, and drives the best-scored one:
            a pass to the left and one to the right stay two candidates instead of being
            averaged into a drive straight on, which a mean-squared fit does where the
            demonstrator's choice of side is a sharp function of the grid (docs/notebook/training_studies.md,
            "Where the clones' drives leave the expert's").
        bin_edges: Which candidate learns a label in the behaviour-cloning fit. Empty: the
            candidate nearest the label (multiple-choice learning). K - 1 increasing steering
            values: candidate k learns the labels between edges k - 1 and k, so each stands for
            one kind of manoeuvre (with (-0.3, 0.3): pass left, straight on, pass right; 0.3 is
            ``WarmStartConfig.strong_steer``) and the scores learn which, a question with an
            answer even where the candidates' values are alike.
        choice_weight: Weight, in the behaviour-cloning loss, of the scores' cross-entropy
            against the candidate that learns the label. 0.1: the squared steering errors are
            ~0.01, a cross-entropy of ~0.1-1 at full weight would swamp them in the shared layers.
        other_modes_weight: Without ``bin_edges``: share of the squared error of all candidates
            in the fit (the rest is the nearest one's; Rupprecht et al. 2017, relaxed
            winner-takes-all), so that a candidate no label is nearest to still moves towards
            the data instead of dying.
        route_offset_m: > 0: the policy outputs a lateral offset from the centre line, up to this
            many metres either way, and steers towards it by pure pursuit
            (:mod:`negobs_gym.policies.route_offset`); 0: it outputs the steering itself. 3 m is
            half the winding course's 6 m track: every target lies on the track.
        route_point_m: With ``route_offset_m``: the route point (one of
            ``observation.route_points_m``, with one beyond it for the route's direction) that the
            offset shifts; 5 m, the first point beyond pure pursuit's 4 m look-ahead.
    """

    modes: int = 1
    bin_edges: tuple[float, ...] = ()
    choice_weight: float = 0.1
    other_modes_weight: float = 0.05
    route_offset_m: float = 0.0
    route_point_m: float = 5.0

    def __post_init__(self) -> None:
        modes = self.modes
        require(isinstance(modes, int) and modes >= 1, "modes", f"must be an int >= 1, got {modes!r}")
        edges = tuple(self.bin_edges)
        require(
            not edges or len(edges) == modes - 1,
            "bin_edges",
            f"needs one edge between each two of the {modes} candidates, got {edges}",
        )
        require(
            all(math.isfinite(e) and -1 < e < 1 for e in edges) and list(edges) == sorted(set(edges)),
            "bin_edges",
            f"must be increasing steering values in (-1, 1), got {edges}",
        )
        require(
            math.isfinite(self.choice_weight) and self.choice_weight > 0,
            "choice_weight",
            f"must be finite and > 0, got {self.choice_weight!r}",
        )
        require(
            math.isfinite(self.other_modes_weight) and 0 <= self.other_modes_weight < 1,
            "other_modes_weight",
            f"must be in [0, 1), got {self.other_modes_weight!r}",
        )
        require(
            math.isfinite(self.route_offset_m) and self.route_offset_m >= 0,
            "route_offset_m",
            f"must be finite and >= 0, got {self.route_offset_m!r}",
        )
        require(
            math.isfinite(self.route_point_m) and self.route_point_m > 0,
            "route_point_m",
            f"must be finite and > 0, got {self.route_point_m!r}",
        )
        require(
            self.route_offset_m == 0 or modes == 1,
            "route_offset_m",
            "steers by one offset: leave modes at 1 with it",
        )


def steering_head(modes: int = 1, bin_edges: tuple[float, ...] = ()) -> SteeringHeadConfig:
    """The steering head of ``negobs train --steering-modes K --steering-bins E...``: bin edges
    alone (``modes`` left at 1) give their number of candidates, ``len(bin_edges) + 1``."""
    edges = tuple(bin_edges)
    return SteeringHeadConfig(modes=len(edges) + 1 if edges and modes == 1 else modes, bin_edges=edges)


@dataclass(frozen=True, kw_only=True)
class WarmStartConfig:
    """Behaviour cloning of a scripted driver (:mod:`negobs_gym.policies.pretrain`; the values
    are choices).

    Attributes:
        steps: Demonstration env steps (0: no warm start).
        driver: The demonstrator: ``"pure_pursuit"`` follows the centre line (and drives into the
            first obstacle); ``"track_planner"`` (:mod:`negobs_gym.drivers.track_planner`) passes
            the ground-truth obstacles on the track, which OffroadTrack-v0 needs;
            ``"grid_planner"`` (:mod:`negobs_gym.drivers.grid_planner`) passes the obstacles the
            env's grid shows, so its labels depend on what the policy sees (and 3 s of it).
        dagger_rounds: Rounds of DAgger after the first fit (Ross et al. 2011): the cloned policy
            drives ``steps`` more steps (with the same noise), the driver labels the states it
            visits, and the policy is refitted on everything so far. Cloning alone drifts into
            states the driver never showed (on OffroadTrack-v0 the car leaves the track).
        planner_sight_m: With ``driver="track_planner"``: how far ahead the planner sees
            obstacles (``TrackPlannerConfig.sight_m``; 0: the whole course). 14 m, the range of
            OffroadTrack-v0's oracle grid, labels with no more than the policy can see.
        planner_horizon_m: With ``driver="track_planner"``: > 0 plans again at every step from
            where the car is, this far ahead (``TrackPlannerConfig.plan_horizon_m``), so each label
            depends only on the car's state and the obstacles in sight, as the policy's action
            must; 0: one path, planned again only when the car strays or an obstacle comes into
            sight (its labels also depend on where the path was planned from).
        driver_settings: Fields of the demonstrator's config, nested as the config nests them,
            as a scenario's ``run.driver_settings`` sets them for its driver: ``{"planner":
            {"bend_steps": 1}}`` demonstrates the grid planner's heading lattice
            (docs/training.md). A field the config lacks or refuses is an error when this config
            is built, before any episode runs.
        mirror: Also fit every demonstrated step's mirror image (grid columns reversed, lateral
            state and steering negated; :meth:`~negobs_gym.policies.pretrain.Demonstrations.mirrored`):
            the car and the rules are left-right symmetric, so this doubles the data for free and
            shows each obstacle layout passed on both sides.
        hold_out_every: K > 1: the steps of every K-th demonstration episode are left out of the
            fit and scored after each epoch, and the policy keeps the epoch with the lowest
            held-out loss (early stopping on courses the fit never saw); 0: fit on all, keep the
            last epoch.
        demonstrations: A ``demonstrations.npz`` an earlier run wrote (``OUT/demonstrations.npz``):
            the first fit uses its labelled steps instead of collecting ``steps`` new ones, and
            DAgger rounds add to them (episodes numbered after its own). Refitting a saved
            aggregate with other fit settings takes minutes; collecting it took most of an hour.
        workers: Processes that drive the demonstration episodes, each with its own env (and copy
            of the policy in DAgger rounds); the steps are the same for any count.
        strong_steer: A demonstrated step whose steering label exceeds this in magnitude counts
            as a pass (0.3: where the clones fall short of the expert, docs/notebook/training_studies.md,
            "Where the clones' drives leave the expert's").
        strong_steer_repeats: How often each pass step enters every epoch of the fit (1: once,
            like any step). Passes are a third of the steps; a mean-squared fit averages them with
            the straight driving around them and steers them too late or too gently.
        noise_std: Std of the Gaussian noise added to the executed steering and throttle (the
            labels stay clean), so the demonstrations include recoveries towards the route.
        epochs: Passes over the demonstrations.
        batch_size: Minibatch size of the fit.
        learning_rate: Adam step size of the fit.
        weight_decay: Decoupled weight decay of the fit (AdamW; 0: plain Adam), a regulariser
            against fitting the demonstration courses instead of what carries to new ones.
        action_std: The policy's action standard deviation after the fit (PPO's exploration;
            SB3 starts at 1.0, which drives a cloned route follower off the track at once).
    """

    steps: int = 0
    driver: str = "pure_pursuit"
    dagger_rounds: int = 0
    planner_sight_m: float = 0.0
    planner_horizon_m: float = 0.0
    driver_settings: Mapping[str, Any] = field(default_factory=dict)
    mirror: bool = False
    hold_out_every: int = 0
    demonstrations: str = ""
    workers: int = 1
    strong_steer: float = 0.3
    strong_steer_repeats: int = 1
    noise_std: float = 0.3
    epochs: int = 20
    batch_size: int = 256
    learning_rate: float = 1e-3
    weight_decay: float = 0.0
    action_std: float = 0.3

    @property
    def enabled(self) -> bool:
        """Whether there is a warm start: demonstration steps to collect or a file to start from."""
        return self.steps > 0 or bool(self.demonstrations)

    def __post_init__(self) -> None:
        require(
            isinstance(self.steps, int) and self.steps >= 0,
            "steps",
            f"must be an int >= 0, got {self.steps!r}",
        )
        for name in ("epochs", "batch_size", "workers", "strong_steer_repeats"):
            value = getattr(self, name)
            require(isinstance(value, int) and value >= 1, name, f"must be an int >= 1, got {value!r}")
        require(
            isinstance(self.dagger_rounds, int) and self.dagger_rounds >= 0,
            "dagger_rounds",
            f"must be an int >= 0, got {self.dagger_rounds!r}",
        )
        require(
            isinstance(self.hold_out_every, int) and (self.hold_out_every == 0 or self.hold_out_every >= 2),
            "hold_out_every",
            f"must be 0 (no hold-out) or an int >= 2, got {self.hold_out_every!r}",
        )
        require(isinstance(self.mirror, bool), "mirror", f"must be a bool, got {self.mirror!r}")
        require(
            self.steps > 0 or self.dagger_rounds == 0,
            "dagger_rounds",
            "each DAgger round collects `steps` new steps (--warm-start-steps): set it >= 1",
        )
        for name in (
            "noise_std",
            "learning_rate",
            "weight_decay",
            "action_std",
            "planner_sight_m",
            "planner_horizon_m",
            "strong_steer",
        ):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, name, f"must be finite and >= 0, got {value!r}")
        require(self.action_std > 0, "action_std", "must be > 0")
        require(
            self.driver in DEMONSTRATORS,
            "driver",
            f"unknown demonstrator {self.driver!r}; expected one of {DEMONSTRATORS}",
        )
        if self.driver_settings:
            from negobs_gym.drivers import driver_config  # imports the simulator: only when needed

            driver_config(self.driver, settings=self.driver_settings)  # ConfigError: driver_settings


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """One training run. The RL papers' defaults are SB3's; the fields that differ say why.

    The env is ``env``'s scenario spec with :data:`TRAINING_DEFAULTS`, then ``overrides``, applied:
    the one description of what trains, including the grid source (``observation.source``) and
    the safety filter (``run.filter``, ``filter.stop_for_positive``), which the run reads from it.

    Attributes:
        env: A registered negobs env id, a shipped scenario name or a scenario TOML path.
        overrides: ``KEY.PATH=VALUE`` settings of that scenario changed, in order (the commands'
            ``--set``; :func:`negobs_gym.spec.apply_overrides`), e.g.
            ``("observation.source=oracle", "run.filter=true")``.
        grid_input: The policy sees the grid; False: the state vector alone (``--source state``;
            the env still computes its grid, for the filter and ``info``).
        algo: ``"PPO"`` or ``"SAC"``.
        steps: Total env steps (over all envs).
        envs: Parallel envs (processes when > 1, see ``vec_env``).
        vec_env: With ``envs`` > 1: ``"build_ahead"``
            (:class:`~negobs_gym.envs.build_ahead.BuildAheadVecEnv`: SB3's ``SubprocVecEnv`` whose
            workers, while they wait for a policy update or another env's reset, build the world
            of their next episode, so most resets skip the build; one more world in memory per
            env), ``"subproc"`` (SB3's ``SubprocVecEnv``: a finished episode builds its next world
            inside the lockstep while the other envs wait; the same episodes as ``build_ahead``)
            or ``"prefetch"`` (:class:`~negobs_gym.envs.vector.PrefetchVecEnv`: a spare process
            per env resets the next episode beforehand; twice the processes and memory; another
            episode stream from the same seed) or ``"ray"``
            (:class:`~negobs_gym.policies.ray_envs.RayVecEnv`: each env a Ray actor, on a cluster
            or a local instance, also for ``envs`` = 1; the same episodes as ``subproc``). Rates:
            docs/notebook/performance.md, "Vector envs".
        ray_address: With ``vec_env="ray"``: the Ray cluster to join (``"auto"``,
            ``"ray://host:10001"``); ``""`` starts a local instance (or joins the one this
            process already runs).
        seed: Seed of the algorithm and of the envs' first resets (env ``i`` gets ``seed + i``).
        eval_every: Env steps between evaluations (0: only at the end).
        eval_episodes: Episodes per evaluation, on seeds ``eval_seed + k``.
        eval_seed: First evaluation seed; far from the training seeds, so the evaluation
            terrains are unseen, and below the block 1,000,000.. that ``negobs eval policy`` and
            the recipes judge on, so picking a checkpoint by its evaluations does not pick it on
            the judged seeds.
        checkpoint_every: Env steps between checkpoints (0: none).
        n_steps: PPO rollout length per env; 256 instead of SB3's 2048 so a 2-core machine
            updates every few hundred steps.
        batch_size: Minibatch size (SB3's PPO default 64).
        learning_rate: Adam step size (SB3's default 3e-4 for both algorithms).
        gamma: Discount (SB3's default 0.99: a 10 s horizon at 10 Hz).
        buffer_size: SAC replay buffer in transitions; 100 k instead of SB3's 1 M because each
            holds two 2304-byte grids (1 M would need ~4.6 GB).
        extractor: The CNN's layers.
        head: The steering head: one Gaussian mean (SB3's), or K scored candidates (PPO only).
        warm_start: Behaviour cloning of the pure-pursuit driver before training (new PPO runs
            only; ``steps=0``, the default, trains from scratch).
        init_model: Start a new run from this trained model's weights (a saved ``.zip`` or a
            shipped baseline's name) instead of a fresh network: a curriculum, e.g. oracle grid
            first, then the detector grid behind the filter. Its algorithm must be ``algo`` and its
            observation space the env's; ``learning_rate``, ``n_steps``, ``batch_size``, ``gamma``
            and ``seed`` are this config's, and the step count starts at 0. ``""``: no init.
        init_action_std: PPO with ``init_model``: set the policy's action standard deviation to
            this before training (its exploration; a cloned policy's deterministic action can
            reach goals that its std-0.3 samples do not). 0: keep the model's.
        critic_warmup_steps: PPO: for the first this many env steps only the value function
            learns; the features extractor, the actor and its log_std stay frozen. A cloned or
            ``init_model`` actor otherwise takes its first updates from a random critic's
            advantages, which on OffroadTrack-v0 undid the clone within 10 k steps
            (docs/notebook/training_studies.md). 0: none.
        target_kl: PPO: stop an update's epochs once the approximate KL divergence to the
            rollout's policy exceeds 1.5 x this (SB3's ``target_kl``); keeps a fine-tuned actor
            near the one that collected the data. 0: no limit (SB3's default).
        torch_threads: Torch intra-op threads while training. 1: measured on the 2 shared cores,
            one ``predict`` of the default network took 45 ms with 2 threads (OpenMP waiting for
            a busy core) and 1.0 ms with 1; the network is too small to gain from more.
        progress: Show a tqdm progress bar.
    """

    env: str = "negobs_gym/OffroadNav-v0"
    overrides: tuple[str, ...] = ()
    grid_input: bool = True
    algo: str = "PPO"
    steps: int = 100_000
    envs: int = 1
    vec_env: str = "build_ahead"
    ray_address: str = ""
    seed: int = 0
    eval_every: int = 10_000
    eval_episodes: int = 5
    eval_seed: int = 900_000
    checkpoint_every: int = 10_000
    n_steps: int = 256
    batch_size: int = 64
    learning_rate: float = 3e-4
    gamma: float = 0.99
    buffer_size: int = 100_000
    extractor: GridCnnConfig = field(default_factory=GridCnnConfig)
    head: SteeringHeadConfig = field(default_factory=SteeringHeadConfig)
    warm_start: WarmStartConfig = field(default_factory=WarmStartConfig)
    init_model: str = ""
    init_action_std: float = 0.0
    critic_warmup_steps: int = 0
    target_kl: float = 0.0
    torch_threads: int = 1
    progress: bool = True
    # Deprecated (one release): the copies of scenario settings TrainConfig held, translated
    # into `overrides` and `grid_input` (legacy_settings).
    source: InitVar[str | None] = None
    filter: InitVar[bool | None] = None
    stop_for_positive: InitVar[bool | None] = None

    def __post_init__(self, source: str | None, filter: bool | None, stop_for_positive: bool | None) -> None:
        old = {"source": source, "filter": filter, "stop_for_positive": stop_for_positive}
        given = {k: v for k, v in old.items() if v is not None}
        if given:
            overrides, grid_input = legacy_settings(**given)
            warnings.warn(
                f"TrainConfig({'=..., '.join(given)}=...) is deprecated: give the scenario settings as "
                f"overrides={overrides!r} and the policy's input as grid_input={grid_input}",
                DeprecationWarning,
                stacklevel=3,
            )
            object.__setattr__(self, "overrides", (*self.overrides, *overrides))
            object.__setattr__(self, "grid_input", grid_input and self.grid_input)
        require(
            isinstance(self.env, str) and bool(self.env), "env", f"must be a non-empty text, got {self.env!r}"
        )
        require(
            isinstance(self.overrides, tuple)
            and all(isinstance(o, str) and "=" in o for o in self.overrides),
            "overrides",
            f"must be a tuple of KEY.PATH=VALUE texts (the --set paths), got {self.overrides!r}",
        )
        require(isinstance(self.grid_input, bool), "grid_input", f"must be a bool, got {self.grid_input!r}")
        require(isinstance(self.ray_address, str), "ray_address", f"must be a text, got {self.ray_address!r}")
        require(
            not self.ray_address or self.vec_env == "ray",
            "ray_address",
            f"is where the Ray actors run: needs vec_env='ray', got {self.vec_env!r}",
        )
        require(self.algo in ALGORITHMS, "algo", f"unknown algorithm {self.algo!r}; one of {ALGORITHMS}")
        require(
            self.vec_env in VEC_ENVS, "vec_env", f"unknown vector env {self.vec_env!r}; one of {VEC_ENVS}"
        )
        for name in (
            "steps",
            "envs",
            "eval_episodes",
            "n_steps",
            "batch_size",
            "buffer_size",
            "torch_threads",
        ):
            value = getattr(self, name)
            require(isinstance(value, int) and value >= 1, name, f"must be an int >= 1, got {value!r}")
        for name in ("seed", "eval_every", "eval_seed", "checkpoint_every", "critic_warmup_steps"):
            value = getattr(self, name)
            require(isinstance(value, int) and value >= 0, name, f"must be an int >= 0, got {value!r}")
        require(0 < self.learning_rate < 1, "learning_rate", f"must be in (0, 1), got {self.learning_rate}")
        require(0 < self.gamma <= 1, "gamma", f"must be in (0, 1], got {self.gamma}")
        require(
            math.isfinite(self.target_kl) and self.target_kl >= 0,
            "target_kl",
            f"must be finite and >= 0, got {self.target_kl!r}",
        )
        require(
            math.isfinite(self.init_action_std) and self.init_action_std >= 0,
            "init_action_std",
            f"must be finite and >= 0, got {self.init_action_std!r}",
        )
        require(
            not self.init_action_std or self.init_model,
            "init_action_std",
            "needs init_model (the model it sets)",
        )
        for name in ("critic_warmup_steps", "target_kl", "init_action_std"):
            require(not getattr(self, name) or self.algo == "PPO", name, "is a PPO option")
        require(isinstance(self.extractor, GridCnnConfig), "extractor", "must be a GridCnnConfig")
        require(isinstance(self.head, SteeringHeadConfig), "head", "must be a SteeringHeadConfig")
        require(
            (self.head.modes == 1 and self.head.route_offset_m == 0) or self.algo == "PPO",
            "head",
            "steering candidates and route offsets replace a Gaussian policy's mean: PPO only",
        )
        require(isinstance(self.warm_start, WarmStartConfig), "warm_start", "must be a WarmStartConfig")
        require(
            not self.warm_start.enabled or self.algo == "PPO",
            "warm_start",
            "behaviour cloning sets a Gaussian policy's log_std: PPO only",
        )
        require(
            not (self.init_model and (self.head.modes > 1 or self.head.route_offset_m > 0)),
            "head",
            "init_model brings its own head: leave modes at 1 and route_offset_m at 0 with it",
        )
        require(
            not (self.init_model and self.warm_start.enabled),
            "init_model",
            "starts from trained weights: no warm start with it (no warm_start steps or demonstrations)",
        )


def source_settings(source: str) -> tuple[tuple[str, ...], bool]:
    """``(overrides, grid_input)`` of a training run's ``--source``: the scenario's grid source
    (``observation.source=detector``, ``oracle`` or ``pem``), or ``state``, no grid in the policy's input
    and the oracle's grid, the cheapest, in the env (as :func:`negobs_gym.envs.source_overrides`).

    Raises:
        ConfigError: not one of :data:`SOURCES` (field ``source``).
    """
    require(source in SOURCES, "source", f"unknown source {source!r}; one of {SOURCES}")
    grid_input = source != "state"
    return (f"observation.source={source if grid_input else 'oracle'}",), grid_input


def legacy_settings(
    source: str | None = None,
    filter: bool | None = None,  # the old field's name
    stop_for_positive: bool | None = None,
) -> tuple[tuple[str, ...], bool]:
    """``(overrides, grid_input)`` for the scenario settings a :class:`TrainConfig` and its
    ``train.json`` copied before they were read from the spec: ``source`` as
    :func:`source_settings`, ``filter`` as ``run.filter``, ``stop_for_positive`` as
    ``filter.stop_for_positive`` (None: not given).

    Raises:
        ConfigError: a value of the wrong kind (the old field's name and its new path).
    """
    overrides, grid_input = source_settings(source) if source is not None else ((), True)
    for name, path, value in (
        ("filter", "run.filter", filter),
        ("stop_for_positive", "filter.stop_for_positive", stop_for_positive),
    ):
        if value is not None:
            require(isinstance(value, bool), name, f"(now {path}) must be a bool, got {value!r}")
            overrides += (f"{path}={str(value).lower()}",)
    return overrides, grid_input


def config_from_record(record: Mapping[str, Any]) -> TrainConfig:
    """The :class:`TrainConfig` of a ``train.json``'s ``"config"`` table, written by this version
    or an earlier one: the scenario settings earlier versions copied (``source``, ``filter``,
    ``stop_for_positive``) become ``overrides`` after the recorded ones, and ``grid_input``
    (:func:`legacy_settings`).

    Raises:
        ConfigError: a key no version had (its path), or a value the configs refuse.
    """
    data = dict(record)
    old = {k: data.pop(k) for k in ("source", "filter", "stop_for_positive") if k in data}
    overrides, grid_input = legacy_settings(**old)
    data["overrides"] = (*data.get("overrides", ()), *overrides)
    data["grid_input"] = data.get("grid_input", True) if grid_input else False
    return _from_dict(TrainConfig, data, "config")


def _from_dict(cls: type, data: Mapping[str, Any], where: str, name_errors: bool = False) -> Any:
    """``cls`` (a config dataclass) from its :func:`dataclasses.asdict` form read back from JSON
    or TOML: nested configs from their tables, lists as tuples. With ``name_errors`` a value the
    config refuses is named by its full path (``train.warm_start.steps``, not ``steps``)."""
    defaults = cls()
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ConfigError(f"{where}.{unknown[0]}", f"no such setting; {cls.__name__} has {', '.join(names)}")
    values = {}
    for name, value in data.items():
        default = getattr(defaults, name)
        if dataclasses.is_dataclass(default) and isinstance(value, Mapping):
            value = _from_dict(type(default), value, f"{where}.{name}", name_errors)
        elif isinstance(default, tuple) and isinstance(value, list):
            value = tuple(value)
        values[name] = value
    if not name_errors:
        return cls(**values)
    try:
        return cls(**values)
    except ConfigError as error:
        if error.field.startswith(f"{where}."):  # a nested table's, already named in full
            raise
        raise ConfigError(f"{where}.{error.field}", error.message) from None
