"""Env throughput: control steps per second per observation and process count, the bars' ceilings,
resets, memory over a long episode stream, physics and PPO training.

The detector-grid rates drive OffroadNav-v0 (the default observation: paper N's native rig cast
in the grid's region of interest, + LUX, both detectors every step), the oracle rate OffroadNav-v1
(the ground-truth grid the shipped policies were trained on). A constant half-throttle action
drives; a finished episode is reset with the next seed, and the rates count step time alone
(resets are figures of their own).
"""

from __future__ import annotations

import functools
import os
import resource
import tempfile
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from negobs_gym.bench.harness import Clock, Figure, Figures, Suite, positive_counts
from negobs_gym.detector import NegativeObstacleDetector, TraversableRegionDetector
from negobs_gym.envs import make_env, perception
from negobs_gym.envs.vector import PrefetchVecEnv
from negobs_gym.policies.config import TrainConfig
from negobs_gym.policies.training import train
from negobs_gym.sensors.lidar import PendingRigScan
from negobs_gym.sensors.raycast import embree_backend
from negobs_gym.sim import presets
from negobs_gym.sim.events import EventMonitor
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

DETECTOR_ENV = "negobs_gym/OffroadNav-v0"
ORACLE_ENV = "negobs_gym/OffroadNav-v1"
ACTION = np.array([0.5, 0.0], np.float32)  # half throttle, straight ahead
COURSE_M = 200.0  # the physics figures' course length
PROCESSES = 2  # the vector run's worker processes
STAGE_NAMES = {
    "physics": "physics (PyBullet sub-steps, event checks)",
    "scan": "the LiDAR scan (casts, noise, range images)",
    "paper_n": "paper N's detector",
    "paper_t": "paper T's detector",
}


@dataclass(frozen=True)
class EnvSize:
    """How much the env suite drives."""

    steps: int  # control steps of each one-process rate
    rounds: int  # alternating rounds of the oracle and PEM rates ...
    round_steps: int  # ... of this many steps each
    vec_steps: int  # lockstep steps of the 2-process run
    resets: int  # resets timed with a new terrain each
    pool: int  # terrain_pool_size of the pooled resets
    pool_resets: int  # resets timed with the pool (its first `pool` build their terrain)
    memory_steps: int  # random-action steps of the memory figure ...
    memory_warmup: int  # ... of which the first are warm-up
    physics_s: float  # simulated seconds of the physics rate
    courses: int  # new courses built for the build time
    train_steps: int  # PPO env steps (2 envs)
    n_steps: int  # PPO rollout length per env

    def __post_init__(self) -> None:
        positive_counts(self)


class Drive:
    """Half-throttle steps of one env, timed in parts: one untimed reset and step first, and a
    finished episode reset (untimed) with the next seed."""

    def __init__(self, env: gym.Env) -> None:
        self.env, self.seed = env, 0
        env.reset(seed=0)
        env.step(ACTION)

    def steps(self, count: int) -> Clock:
        """The clock of the next ``count`` steps."""
        clock = Clock()
        for _ in range(count):
            with clock:
                _, _, terminated, truncated, _ = self.env.step(ACTION)
            if terminated or truncated:
                self.seed += 1
                self.env.reset(seed=self.seed)
        return clock


def drive(env: gym.Env, steps: int) -> Clock:
    """The clock of ``steps`` half-throttle steps (:class:`Drive`)."""
    return Drive(env).steps(steps)


def _rate(env_id: str, overrides: Sequence[str], steps: int) -> Clock:
    env = make_env(env_id, overrides)
    try:
        return drive(env, steps)
    finally:
        env.close()


#: The stages of a step timed on the stepping thread: (figure name, owner, function).
STAGES = (
    ("physics", World, "step"),  # PyBullet sub-steps and the event checks
    ("scan", perception, "start_rig_scan"),  # the rig's casts, noise, range images ...
    ("scan", PendingRigScan, "scan"),  # ... and the waits for the pool thread's part
    ("paper_n", NegativeObstacleDetector, "update"),
    ("paper_t", TraversableRegionDetector, "update"),
)


@contextmanager
def profiled(env: gym.Env) -> Iterator[list[dict[str, float]]]:
    """Per step of ``env`` on this thread: the wall seconds of the step (``step``) and of each of
    :data:`STAGES` in it, and the thread's CPU seconds outside the Embree casts it runs itself
    (``serial``: the part of a step that more cast threads cannot take over)."""
    me, stepping = threading.get_ident(), [False]
    now: dict[str, float] = defaultdict(float)
    rows: list[dict[str, float]] = []
    originals = []

    def timed(owner: object, attr: str, stage: str, clock: Callable[[], float]) -> None:
        original = getattr(owner, attr)
        originals.append((owner, attr, original))

        def wrapper(*args, **kwargs):
            if not stepping[0] or threading.get_ident() != me:
                return original(*args, **kwargs)
            t = clock()
            try:
                return original(*args, **kwargs)
            finally:
                now[stage] += clock() - t

        setattr(owner, attr, wrapper)

    for stage, owner, attr in STAGES:
        timed(owner, attr, stage, time.perf_counter)
    timed(embree_backend._Scene, "cast", "cast_cpu", time.thread_time)
    step = env.step

    def profiled_step(action):
        now.clear()
        stepping[0], wall, cpu = True, time.perf_counter(), time.thread_time()
        try:
            return step(action)
        finally:
            stepping[0] = False
            serial = time.thread_time() - cpu - now.pop("cast_cpu", 0.0)
            rows.append({**now, "step": time.perf_counter() - wall, "serial": serial})

    env.step = profiled_step
    try:
        yield rows
    finally:
        del env.step
        for owner, attr, original in reversed(originals):
            setattr(owner, attr, original)


def _two_processes(steps: int) -> float:
    """Steps/s (all slots') of the default observation in ``PROCESSES`` workers (``PrefetchVecEnv``)."""
    thunk = functools.partial(make_env, DETECTOR_ENV)
    venv = PrefetchVecEnv([thunk] * PROCESSES)
    try:
        venv.seed(0)
        venv.reset()
        actions = np.tile(ACTION, (PROCESSES, 1))
        venv.step(actions)
        venv.wait_for_spares()  # the spares' first episodes are start-up, not the steady state
        with Clock() as clock:
            for _ in range(steps):
                venv.step(actions)
    finally:
        venv.close()
    return clock.rate(PROCESSES * steps)


def default_observation(size: EnvSize) -> Figures:
    """The default observation in one process, on one cast thread and in 2 processes, and the
    ceilings those give: what the machine's cores and one process's serial part allow."""
    env = make_env(DETECTOR_ENV)
    try:
        with profiled(env) as rows:
            default = drive(env, size.steps)
    finally:
        env.close()
    one_thread = _rate(DETECTOR_ENV, ("observation.raycast_threads=1",), size.steps)
    two = _two_processes(size.vec_steps)
    cores = len(os.sched_getaffinity(0))
    rate = default.rate(size.steps)
    per_step = {
        k: np.mean([row.get(k, 0.0) for row in rows[-size.steps :]]) for k in ("step", "serial", *STAGE_NAMES)
    }
    stages = {
        f"stage_{name}_ms": Figure(1e3 * per_step[name], "ms", f"{what} per step (wall)")
        for name, what in STAGE_NAMES.items()
    }
    stages["stage_other_ms"] = Figure(
        1e3 * (per_step["step"] - sum(per_step[name] for name in STAGE_NAMES)),
        "ms",
        "the rest of a step per step (wall): observation, info, Python",
    )
    figures = {
        "env_steps_per_s": Figure(rate, "steps/s", "default observation, one process"),
        "step_cpu_ms": Figure(1e3 * default.cpu_s / size.steps, "ms", "CPU per step, all threads"),
        "cpu_bound_steps_per_s": Figure(
            cores * size.steps / one_thread.cpu_s,
            "steps/s",
            f"ceiling on {cores} cores: the cores over a one-thread step's CPU",
        ),
        "serial_bound_steps_per_s": Figure(
            1.0 / per_step["serial"],
            "steps/s",
            "ceiling of one process on any number of cores: one over its serial part",
        ),
        "two_process_steps_per_s": Figure(two, "steps/s", f"{PROCESSES} processes, PrefetchVecEnv"),
        "two_process_over_one": Figure(two / rate, "x", f"{PROCESSES} processes over the default process"),
        "two_process_bound": Figure(
            min(PROCESSES, cores) * one_thread.rate(size.steps) / rate,
            "x",
            f"the most {PROCESSES} one-thread workers could scale over the default process",
        ),
    }
    return figures | stages


def oracle_and_pem(size: EnvSize) -> Figures:
    """OffroadNav-v1 on the oracle grid and on the PEM grid, one process each, in short alternating
    rounds (each env driving on where its last round stopped, both on the same courses and steps):
    the medians over the rounds, and the median of the rounds' ratios, which a machine whose
    speed drifts within a minute leaves alone, as two runs one after the other are not."""
    rounds: dict[str, list[float]] = {"oracle": [], "pem": []}
    envs = {source: make_env(ORACLE_ENV, (f"observation.source={source}",)) for source in rounds}
    try:
        drives = {source: Drive(env) for source, env in envs.items()}
        for _ in range(size.rounds):
            for source, rates in rounds.items():
                rates.append(drives[source].steps(size.round_steps).rate(size.round_steps))
    finally:
        for env in envs.values():
            env.close()
    ratios = np.divide(rounds["pem"], rounds["oracle"])
    what = f"median of {size.rounds} alternating rounds of {size.round_steps} steps"
    return {
        "oracle_steps_per_s": Figure(
            float(np.median(rounds["oracle"])),
            "steps/s",
            f"oracle grid, OffroadNav-v1 (the training env); {what}",
        ),
        "pem_steps_per_s": Figure(
            float(np.median(rounds["pem"])),
            "steps/s",
            f"PEM grid (the shipped model), OffroadNav-v1, beside the oracle's; {what}",
        ),
        "pem_over_oracle": Figure(
            float(np.median(ratios)),
            "x",
            f"PEM grid over oracle grid, median of the {size.rounds} rounds' ratios",
        ),
    }


def other_observations(size: EnvSize) -> Figures:
    """One process with another rig or a LiDAR frame every k-th step."""
    runs = {
        "native_rig_steps_per_s": (DETECTOR_ENV, ("observation.rig=native",), "full 360° native rig"),
        "reduced_rig_steps_per_s": (DETECTOR_ENV, ("observation.rig=reduced",), "half-resolution rig"),
        "scan_every_4_steps_per_s": (
            DETECTOR_ENV,
            ("observation.scan_every=4",),
            "a frame every 4th step, carried between",
        ),
        "scan_every_3_far_8_steps_per_s": (
            DETECTOR_ENV,
            ("observation.scan_every=3", "observation.scan_far_from_m=8"),
            "a frame every 3rd step, the grid beyond 8 m cast between",
        ),
    }
    return {
        key: Figure(_rate(env_id, overrides, size.steps).rate(size.steps), "steps/s", what)
        for key, (env_id, overrides, what) in runs.items()
    }


def reset_costs(size: EnvSize) -> Figures:
    """Mean wall seconds of a reset (first observation included): a new terrain each, and a pool."""
    pool = (f"episode.terrain_pool_size={size.pool}", f"episode.world_cache_size={size.pool}")
    figures = {}
    for key, overrides, count, what in (
        ("reset_new_terrain_s", (), size.resets, "reset with a new terrain"),
        ("reset_terrain_pool_s", pool, size.pool_resets, f"reset with episode.terrain_pool_size={size.pool}"),
    ):
        env = make_env(DETECTOR_ENV, overrides)
        env.reset(seed=0)
        clock = Clock()
        for k in range(count):
            with clock:
                env.reset(seed=1000 + k)
            env.step(ACTION)
        env.close()
        figures[key] = Figure(clock.wall_s / count, "s", f"{what}, mean of {count}")
    return figures


def _rss_mb() -> float:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * resource.getpagesize() / 2**20


def memory(size: EnvSize) -> Figures:
    """Resident memory growth over a long stream of random-action steps with resets, after warm-up
    (``tests/envs/test_memory.py`` bounds it); it may be negative."""
    env = make_env(DETECTOR_ENV)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    at_warmup = _rss_mb()
    for k in range(size.memory_steps):
        action = np.array([rng.uniform(0.2, 1.0), rng.uniform(-0.5, 0.5)], np.float32)
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
        if k + 1 == size.memory_warmup:
            at_warmup = _rss_mb()
    growth = _rss_mb() - at_warmup
    env.close()
    after = size.memory_steps - size.memory_warmup
    return {
        "memory_growth_mb": Figure(
            growth,
            "MB",
            f"resident memory growth over {after:,} steps after {size.memory_warmup:,} of warm-up",
        )
    }


def physics(size: EnvSize) -> Figures:
    """Physics steps/s of the vehicle on a rough course, and the build time of a new course."""
    with World(presets.rough_track(length_m=COURSE_M, seed=0)) as world:
        vehicle = Vehicle(world)
        EventMonitor(world, vehicle)  # its checks run in every physics step, as in the envs
        vehicle.set_speed(25 / 3.6)
        vehicle.apply(0.3, 0.0, 0.0)
        n = round(size.physics_s / world.config.time_step_s)
        with Clock() as stepping:
            world.step(n)
    building = Clock()
    for k in range(size.courses):
        with building, World(presets.winding_course(seed=1 + k, length_m=COURSE_M)) as world:
            Vehicle(world)
            world.step(1)
    return {
        "physics_steps_per_s": Figure(stepping.rate(n), "steps/s", "physics steps (vehicle + event checks)"),
        "course_build_s": Figure(
            building.wall_s / size.courses, "s", f"new {COURSE_M:g} m course: terrain, world and vehicle"
        ),
    }


def training(size: EnvSize) -> Figures:
    """PPO's env steps per second in ``negobs train``'s loop: OffroadNav-v1, 2 envs, on the oracle
    grid and on the PEM grid (what training on the PEM costs beside the oracle)."""
    figures = {}
    for key, source in (("ppo_steps_per_s", "oracle"), ("ppo_pem_steps_per_s", "pem")):
        config = TrainConfig(
            env=ORACLE_ENV,
            overrides=(f"observation.source={source}",),
            steps=size.train_steps,
            envs=2,
            vec_env="build_ahead",
            n_steps=size.n_steps,
            batch_size=min(128, size.n_steps),
            eval_every=0,
            eval_episodes=1,
            checkpoint_every=0,
            seed=0,
            progress=False,
        )
        with tempfile.TemporaryDirectory() as out:
            result = train(config, out)
        figures[key] = Figure(
            result.steps_per_s, "steps/s", f"PPO training, OffroadNav-v1, {source} grid, 2 envs (build-ahead)"
        )
    return figures


SUITE = Suite(
    name="env",
    what="env throughput",
    full=EnvSize(
        steps=200,
        rounds=40,
        round_steps=50,
        vec_steps=100,
        resets=10,
        pool=8,
        pool_resets=100,
        memory_steps=5000,
        memory_warmup=1000,
        physics_s=20.0,
        courses=5,
        train_steps=4096,
        n_steps=512,
    ),
    quick=EnvSize(
        steps=20,
        rounds=2,
        round_steps=10,
        vec_steps=15,
        resets=2,
        pool=2,
        pool_resets=4,
        memory_steps=100,
        memory_warmup=50,
        physics_s=3.0,
        courses=1,
        train_steps=256,
        n_steps=64,
    ),
    measurements=(
        default_observation,
        other_observations,
        oracle_and_pem,
        reset_costs,
        memory,
        physics,
        training,
    ),
)
