"""Control steps per second of a negobs env with the detector grid, per stage, per rig, per process count.

Run: ``python benchmarks/env_step.py [--steps 200] [--envs 2] [--env-id negobs_gym/OffroadNav-v0]
[--skip-others] [--default-only] [--scan-every 2,3] [--far-from 12] [--scan-clock env|episode]
[--cast-threads N] [--worker-threads N]`` (``--default-only``: the default observation's stages
and ``train_steps_per_s`` alone, for alternate runs of two checkouts; ``--cast-threads`` and
``--worker-threads``: the Embree cast threads of the one-process runs and of each vector-env
worker, 2 and 1 by default, for machines with more cores; ``two_process_bound`` is printed for
one-thread workers only)

Configurations (the env's registered config with ``ObservationConfig`` changed):

- ``rig=roi``: the default training observation (paper N's native rig cast only where the grid
  and the detectors' neighbourhoods need it, + LUX; both detectors every step);
- ``rig=native``: the full 360 deg native rig + LUX;
- ``rig=reduced``: the old half-resolution rig;
- ``obs=oracle``: the ground-truth grid (no sensors), for comparison;
- ``scan_every=k`` (``--scan-every``, default 2,3): the default rig with a LiDAR frame every k-th
  step, carried to the current pose between (``ObservationConfig.scan_every``), in one process
  and in ``--envs`` processes (``PrefetchVecEnv``); with ``--far-from M`` each k also with the
  grid's part beyond M metres cast and detected between frames (``scan_far_from_m``). Frames on
  the env's step clock by default (``--scan-clock env``: the processes cast on the same steps).

Reset cost: the mean over an episode stream with a new seed each, with a new terrain every
episode (the default, 10 episodes) and with ``terrain_pool_size=8`` (100 episodes: 8 builds,
then kept worlds restored instead of built). A reset includes the first observation.

A constant half-throttle action drives; finished episodes are reset, their cost included (the
car leaves the winding track after ~100 steps, so resets weigh as they do early in training). The
default rig runs over the same episodes, those of a ``PrefetchVecEnv`` seeded 0 (slot ``i``'s
episode ``k`` seeded ``episode_seed(0, i, k)``, ``--steps / --envs`` steps per slot): in one
process, one env after the other, with per-stage timers (physics = ``World.step``, of which the
event checks; scan synthesis on the calling thread, waits for the cast's pool thread included;
paper N's detector; paper T's detector, which runs while the largest sensor is cast on the pool
thread; the rest of the step: observation stacking, info, Python glue; the reset; CPU: each
stage's on the calling thread, and ``cast_threads`` the pool threads' per step); in one process
casting with one thread, as
each worker does; and vectorized (``--envs`` slots; steps/s counts the steps of all of them) with
``negobs_gym.envs.vector.PrefetchVecEnv`` (a spare process per slot resets the next episode) and,
for comparison, SB3's ``SubprocVecEnv`` (seeded 0; its workers reset inside the lockstep, from
their env's generator, so their later episodes differ). ``ratio`` is a vector rate against the
first one-process run (whose Embree cast runs on 2 threads, the default outside workers),
``ratio_to_one_thread`` against the second: the scaling over processes alone. ``lockstep_ms``
says where a vector run loses against that, per lockstep step (both wait for every slot at each
step): the slots' own step time (CPU, against the one-thread process: what the shared machine
costs), the wait for the slower slot, the resets and the rest (pipes, the main process, waits for
a spare). ``cpu_bound_steps_per_s`` is the most steps/s this machine's cores could give for the
default observation's work however it were spread over threads or processes: the cores over the
one-thread process's CPU per step (a step's work, without a second thread's waits);
``two_process_bound`` the most a ``--envs``-process run could scale over the default process, the
one-thread rate times the processes the cores can run at once, over the default process's rate
(each bar of the training-throughput issue is out of reach on a machine where its bound is under
it). ``serial_bound_steps_per_s`` is the most one process of this code could give on any number
of cores: one over the stepping thread's CPU per step outside the Embree casts it runs itself
(physics, the scans' set-up and finish, both detectors, the rest: what more cast threads cannot
take over). The last line is ``train_steps_per_s=<v>``: the default observation in one process.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import threading
import time
from collections import defaultdict
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import negobs_gym
from negobs_gym.detector import NegativeObstacleDetector, TraversableRegionDetector
from negobs_gym.envs import base as env_base
from negobs_gym.envs import perception
from negobs_gym.envs.vector import PrefetchVecEnv, episode_seed
from negobs_gym.sensors.lidar import PendingRigScan
from negobs_gym.sensors.raycast import embree_backend
from negobs_gym.sensors.raycast.embree_packets import native_packet_width
from negobs_gym.sim.events import EventMonitor
from negobs_gym.sim.world import World

ACTION = np.array([0.5, 0.0], np.float32)


def _make(env_id: str, source: str, rig: str, threads: int | None = None, **observation):
    """An env factory: ``env_id``'s registered config with the observation's source, rig,
    raycast threads and further ``observation`` fields changed."""

    def thunk():
        # "module:id" makes gymnasium import negobs_gym (and so register) inside a subprocess
        spec_id = f"negobs_gym:{env_id}"
        probe = gym.make(spec_id)
        cfg = probe.unwrapped.default_config()
        probe.close()
        obs = dataclasses.replace(cfg.observation, source=source, rig=rig, **observation)
        if threads is not None:
            obs = dataclasses.replace(obs, raycast_threads=threads)
        return gym.make(spec_id, config=dataclasses.replace(cfg, observation=obs))

    return thunk


class StepClock(gym.Wrapper):
    """Puts each step's wall and process-CPU seconds, and the wall seconds of the resets since the
    step before (0 when none), into ``info`` (``step_wall_s``, ``step_cpu_s``, ``reset_wall_s``,
    ``reset_cpu_s``);
    ``steps`` and ``cpu_s`` sum them."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self._reset_s = 0.0
        self._reset_cpu_s = 0.0
        self.steps = 0
        self.cpu_s = 0.0

    def reset(self, **kwargs):
        t0, c0 = time.perf_counter(), time.process_time()
        out = self.env.reset(**kwargs)
        self._reset_s += time.perf_counter() - t0
        self._reset_cpu_s += time.process_time() - c0
        return out

    def step(self, action):
        t0, c0 = time.perf_counter(), time.process_time()
        obs, reward, term, trunc, info = self.env.step(action)
        cpu = time.process_time() - c0
        self.steps += 1
        self.cpu_s += cpu
        info = dict(info, step_wall_s=time.perf_counter() - t0, step_cpu_s=cpu)
        info["reset_wall_s"], self._reset_s = self._reset_s, 0.0
        info["reset_cpu_s"], self._reset_cpu_s = self._reset_cpu_s, 0.0
        return obs, reward, term, trunc, info


def _clocked(thunk: Callable[[], gym.Env]) -> Callable[[], gym.Env]:
    return lambda: StepClock(thunk())


def _episodes(thunk: Callable[[], gym.Env], n_envs: int) -> list[gym.Env]:
    """``n_envs`` envs as the vector run's slots start: env ``i`` reset with ``episode_seed(0, i,
    0)`` and stepped once (the vector run's first step is outside its timing too)."""
    envs = []
    for i in range(n_envs):
        env = thunk()
        env.reset(seed=episode_seed(0, i, 0))
        env.step(ACTION)
        if isinstance(env, StepClock):
            env.steps, env.cpu_s = 0, 0.0
        envs.append(env)
    return envs


def _drive(envs: list[gym.Env], steps_each: int) -> tuple[float, int]:
    """Steps/s of driving each env ``steps_each`` steps, one env after the other, and the number of
    resets (their cost included): env ``i``'s episode ``k`` is seeded ``episode_seed(0, i, k)``,
    so one process drives exactly the episodes of ``PrefetchVecEnv`` seeded 0."""
    resets = 0
    t0 = time.perf_counter()
    for i, env in enumerate(envs):
        episode = 0
        for _ in range(steps_each):
            _, _, term, trunc, _ = env.step(ACTION)
            if term or trunc:
                episode += 1
                env.reset(seed=episode_seed(0, i, episode))
                resets += 1
    return len(envs) * steps_each / (time.perf_counter() - t0), resets


def _close(envs: list[gym.Env]) -> None:
    for env in envs:
        env.close()


class StageTimer:
    """Wraps functions with accumulating wall-clock and CPU timers (restored on exit).

    CPU time is what a stage costs whatever else loads the machine (``cpu_s``: all threads of
    this process; ``thread_s``: the calling thread's, where the Embree pool threads run beside
    it); wall time is what a trainer waits.
    """

    def __init__(self) -> None:
        self.total_s: dict[str, float] = defaultdict(float)
        self.cpu_s: dict[str, float] = defaultdict(float)
        self.thread_s: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._undo: list[Callable[[], None]] = []
        self._inside: dict[str, list[int]] = defaultdict(list)  # stage -> threads in it now

    def wrap(self, owner: object, attr: str, stage: str, within: str | None = None) -> None:
        """Time ``owner.attr`` as ``stage``; with ``within``, only its calls made inside stage
        ``within`` on the thread that runs it (e.g. a cast by the stepping thread, not by the pool
        threads or a reset)."""
        original = getattr(owner, attr)

        def timed(*args, **kwargs):
            me = threading.get_ident()
            if within is not None and me not in self._inside[within]:
                return original(*args, **kwargs)
            self._inside[stage].append(me)
            t0, c0, h0 = time.perf_counter(), time.process_time(), time.thread_time()
            try:
                return original(*args, **kwargs)
            finally:
                self.total_s[stage] += time.perf_counter() - t0
                self.cpu_s[stage] += time.process_time() - c0
                self.thread_s[stage] += time.thread_time() - h0
                self.calls[stage] += 1
                self._inside[stage].pop()

        setattr(owner, attr, timed)
        self._undo.append(lambda: setattr(owner, attr, original))

    def clear(self) -> None:
        """Forget what was timed so far (a warm-up)."""
        self.total_s.clear()
        self.cpu_s.clear()
        self.thread_s.clear()
        self.calls.clear()

    def __enter__(self) -> StageTimer:
        return self

    def __exit__(self, *exc: object) -> None:
        for undo in reversed(self._undo):
            undo()


Stages = dict[str, float]


def stage_breakdown(
    env_id: str, rig: str, steps_each: int, n_envs: int, threads: int | None = None
) -> tuple[Stages, Stages, float, int]:
    """Wall and CPU milliseconds per control step by stage (reset: per reset), steps/s and resets
    over the vector run's episodes (``n_envs`` seeds, ``steps_each`` steps each). The stages' CPU
    is the calling thread's, ``cast_threads`` the Embree pool threads' (a step's process CPU less
    its calling thread's)."""
    with StageTimer() as timer:
        timer.wrap(World, "step", "physics")
        # wrapped before the envs exist: each monitor registers its bound _check as a step hook
        timer.wrap(EventMonitor, "_check", "events")
        timer.wrap(perception, "start_rig_scan", "scan")
        timer.wrap(PendingRigScan, "scan", "scan")  # each sensor's cast, or the wait for it
        timer.wrap(NegativeObstacleDetector, "update", "paper_n")
        timer.wrap(TraversableRegionDetector, "update", "paper_t")
        timer.wrap(env_base.NegObsEnv, "step", "step")
        # the Embree casts the stepping thread runs itself (its sensors, its share of the shared cast)
        timer.wrap(embree_backend._Scene, "cast", "calling_casts", within="step")
        timer.wrap(env_base.NegObsEnv, "reset", "reset")
        envs = _episodes(_make(env_id, "detector", rig, threads), n_envs)
        timer.clear()  # the first make/reset/step are outside the timing
        sps, resets = _drive(envs, steps_each)
    _close(envs)
    steps = steps_each * n_envs
    cpu_ms = _per_step(timer.thread_s, steps, resets)
    cpu_ms["cast_threads"] = 1e3 * (timer.cpu_s["step"] - timer.thread_s["step"]) / steps
    cpu_ms["calling_thread_outside_casts"] = (
        1e3 * (timer.thread_s["step"] - timer.thread_s["calling_casts"]) / steps
    )
    return _per_step(timer.total_s, steps, resets), cpu_ms, sps, resets


def _per_step(t: dict[str, float], steps: int, resets: int) -> dict[str, float]:
    ms = {k: 1e3 * t[k] / steps for k in ("physics", "events", "scan", "paper_n", "paper_t")}
    inner = t["physics"] + t["scan"] + t["paper_n"] + t["paper_t"]
    ms["other"] = 1e3 * (t["step"] - inner) / steps
    ms["reset_per_reset"] = 1e3 * t["reset"] / resets if resets else float("nan")
    return ms


def reset_stream_s(env_id: str, resets: int, pool: int | None) -> tuple[float, float]:
    """Mean wall and CPU seconds per reset over ``resets`` episodes (a new seed each), default obs.

    ``pool``: ``EnvConfig.terrain_pool_size`` (and as many kept worlds); None = a new terrain each.
    """
    spec_id = f"negobs_gym:{env_id}"
    probe = gym.make(spec_id)
    cfg = probe.unwrapped.default_config()
    probe.close()
    if pool is not None:
        cfg = dataclasses.replace(cfg, terrain_pool_size=pool, world_cache_size=pool)
    env = gym.make(spec_id, config=cfg)
    env.reset(seed=0)
    wall = cpu = 0.0
    for k in range(resets):
        t0, c0 = time.perf_counter(), time.process_time()
        env.reset(seed=1000 + k)
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        env.step(ACTION)
    env.close()
    return wall / resets, cpu / resets


def _fmt(ms: dict[str, float]) -> str:
    return " ".join(f"{k}={v:.2f}" for k, v in ms.items())


def _run_vec(
    env_id: str,
    source: str,
    rig: str,
    steps: int,
    n_envs: int,
    kind: str,
    threads: int | None = None,
    **observation,
) -> tuple[float, dict[str, float]]:
    """Steps/s of an ``n_envs``-slot vector env (all its steps), ``kind`` ``"prefetch"``
    (:class:`~negobs_gym.envs.vector.PrefetchVecEnv`, seeded 0: the episodes of :func:`_drive`) or
    ``"subproc"`` (SB3 ``SubprocVecEnv``, seeded 0: worker ``i`` starts on seed ``i``, then resets
    from its env's generator), and milliseconds per lockstep step: ``total``, ``slowest_step`` (the
    slower slot's step), ``mean_step`` and ``mean_step_cpu`` (one slot's), ``resets`` (summed over
    slots: for ``subproc`` their wall time, in the lockstep; for ``prefetch`` the CPU time they
    took beside it, in the spares), ``rest`` (``total`` less the slower step, less the resets for
    ``subproc``: waits for a spare, pipes, the main process)."""
    from stable_baselines3.common.vec_env import SubprocVecEnv

    thunks = [_clocked(_make(env_id, source, rig, threads, **observation)) for _ in range(n_envs)]
    venv = PrefetchVecEnv(thunks) if kind == "prefetch" else SubprocVecEnv(thunks)
    venv.seed(0)
    venv.reset()
    actions = np.tile(ACTION[None], (n_envs, 1))
    venv.step(actions)  # first step outside the timing (workers warm)
    if isinstance(venv, PrefetchVecEnv):
        venv.wait_for_spares()  # their first episodes: start-up, not the steady state timed here
    wall, cpu, resets = [], [], 0.0
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, _, infos = venv.step(actions)  # finished episodes are replaced by the vector env
        wall.append([i["step_wall_s"] for i in infos])
        cpu.append([i["step_cpu_s"] for i in infos])
        # in the lockstep a reset's wall time counts; beside it (spares), the CPU it took
        resets += sum(i["reset_wall_s" if kind == "subproc" else "reset_cpu_s"] for i in infos)
    dt = time.perf_counter() - t0
    # resets no later step reports (the last ones) are in "rest"
    venv.close()
    w = np.asarray(wall)
    ms = {
        "total": 1e3 * dt / steps,
        "slowest_step": 1e3 * float(w.max(axis=1).mean()),
        "mean_step": 1e3 * float(w.mean()),
        "mean_step_cpu": 1e3 * float(np.mean(cpu)),
        "resets": 1e3 * resets / steps,
    }
    ms["rest"] = ms["total"] - ms["slowest_step"] - (ms["resets"] if kind == "subproc" else 0.0)
    return steps * n_envs / dt, ms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="negobs_gym/OffroadNav-v0")
    parser.add_argument("--steps", type=int, default=200, help="control steps per configuration")
    parser.add_argument("--envs", type=int, default=2, help="processes of the vectorized run")
    parser.add_argument("--skip-others", action="store_true", help="only the default rig")
    parser.add_argument(
        "--default-only",
        action="store_true",
        help="only the default observation in one process (stages, train_steps_per_s): a quick A/B of "
        "two checkouts run alternately",
    )
    parser.add_argument(
        "--scan-every", default="2,3", help="comma-separated ObservationConfig.scan_every values ('' = none)"
    )
    parser.add_argument(
        "--far-from",
        type=float,
        default=None,
        metavar="M",
        help="also run each --scan-every value with ObservationConfig.scan_far_from_m=M",
    )
    parser.add_argument(
        "--scan-clock",
        choices=("env", "episode"),
        default="env",
        help="ObservationConfig.scan_clock of the --scan-every runs (env: processes cast on the same steps)",
    )
    parser.add_argument(
        "--cast-threads",
        type=int,
        default=None,
        metavar="N",
        help="ObservationConfig.raycast_threads of the one-process runs (default: the env's, 2 in a main "
        "process): for machines with more cores",
    )
    parser.add_argument(
        "--worker-threads",
        type=int,
        default=None,
        metavar="N",
        help="ObservationConfig.raycast_threads of the vector-env workers (default: the env's, 1 in a "
        "worker)",
    )
    args = parser.parse_args()
    if args.steps < 1 or args.envs < 1:
        parser.error("--steps and --envs must be >= 1")
    if any(n is not None and n < 1 for n in (args.cast_threads, args.worker_threads)):
        parser.error("--cast-threads and --worker-threads must be >= 1")
    every = [int(k) for k in args.scan_every.split(",") if k.strip()]
    if any(k < 1 for k in every):
        parser.error(f"--scan-every takes ints >= 1, got {args.scan_every!r}")
    default_rig = negobs_gym.envs.config.ObservationConfig().rig
    t0 = time.perf_counter()
    env = _make(args.env_id, "detector", default_rig)()
    env.reset(seed=0)
    print(f"env={args.env_id} first_make_and_reset_s={time.perf_counter() - t0:.2f}")
    print(f"embree_packet_width={native_packet_width()} (16: AVX-512 kernels, 8: AVX2)")
    print(
        f"cast_threads one_process={args.cast_threads or 'default (2)'} "
        f"workers={args.worker_threads or 'default (1)'}"
    )
    env.close()
    if not (args.skip_others or args.default_only):
        for source, rig in (("detector", "native"), ("detector", "reduced"), ("oracle", default_rig)):
            label = f"obs={source}" + (f" rig={rig}" if source == "detector" else "")
            envs = _episodes(_make(args.env_id, source, rig), 1)
            sps, _ = _drive(envs, max(20, args.steps // 4))
            _close(envs)
            print(f"{label} processes=1 steps_per_s={sps:.1f}")
    for pool, episodes in () if args.default_only else ((None, 10), (8, 100)):
        wall_s, cpu_s = reset_stream_s(args.env_id, episodes, pool)
        print(f"reset_s_mean terrain_pool={pool} over {episodes} episodes: {wall_s:.3f} (cpu {cpu_s:.3f})")
    each = max(1, args.steps // args.envs)  # every run below drives the same episodes
    ms, cpu_ms, sps, resets = stage_breakdown(args.env_id, default_rig, each, args.envs, args.cast_threads)
    print(f"stage_ms rig={default_rig} steps={each * args.envs} resets={resets}: {_fmt(ms)}")
    print(f"stage_cpu_ms rig={default_rig}: {_fmt(cpu_ms)}")
    serial_ms = cpu_ms["calling_thread_outside_casts"]
    print(
        f"serial_bound_steps_per_s={1e3 / serial_ms:.1f} (stepping thread, casts aside: {serial_ms:.2f} ms)"
    )
    if args.default_only:
        print(f"train_steps_per_s={sps:.1f}")
        return
    alone = _episodes(_clocked(_make(args.env_id, "detector", default_rig, threads=1)), args.envs)
    one_thread, _ = _drive(alone, each)
    alone_cpu_ms = 1e3 * sum(e.cpu_s for e in alone) / max(1, sum(e.steps for e in alone))
    _close(alone)
    print(
        f"obs=detector rig={default_rig} processes=1 raycast_threads=1 steps_per_s={one_thread:.1f} "
        f"step_cpu_ms={alone_cpu_ms:.1f}"
    )
    cores = len(os.sched_getaffinity(0))
    ceilings = f"cores={cores} cpu_bound_steps_per_s={cores * 1e3 / alone_cpu_ms:.1f}"
    if (args.worker_threads or 1) == 1:  # one-thread workers: at most the one-thread rate each
        ceilings += f" two_process_bound={min(args.envs, cores) * one_thread / sps:.2f}"
    print(ceilings)
    for kind in ("prefetch", "subproc"):
        vec, lockstep = _run_vec(
            args.env_id, "detector", default_rig, each, args.envs, kind, args.worker_threads
        )
        print(
            f"obs=detector rig={default_rig} processes={args.envs} vec={kind} steps_per_s={vec:.1f} "
            f"ratio={vec / sps:.2f} ratio_to_one_thread={vec / one_thread:.2f}"
        )
        alone_note = f"one process alone: step_cpu {alone_cpu_ms:.1f}"
        print(f"lockstep_ms vec={kind} ({alone_note}): {_fmt(lockstep)}")
    fars = (None,) if args.far_from is None else (None, args.far_from)
    for k, far in ((k, far) for k in every for far in fars):
        observation = {"scan_every": k, "scan_far_from_m": far, "scan_clock": args.scan_clock}
        thunk = _make(args.env_id, "detector", default_rig, args.cast_threads, **observation)
        envs = _episodes(_clocked(thunk), args.envs)
        one, _ = _drive(envs, each)
        cpu_ms = 1e3 * sum(e.cpu_s for e in envs) / max(1, sum(e.steps for e in envs))
        _close(envs)
        vec, _ = _run_vec(
            args.env_id,
            "detector",
            default_rig,
            each,
            args.envs,
            "prefetch",
            args.worker_threads,
            **observation,
        )
        label = f"scan_every={k}" + ("" if far is None else f" scan_far_from_m={far:g}")
        label += f" scan_clock={args.scan_clock}"
        print(
            f"obs=detector rig={default_rig} {label} processes=1 steps_per_s={one:.1f} "
            f"step_cpu_ms={cpu_ms:.1f} ratio_to_every_step={one / sps:.2f}; processes={args.envs} "
            f"vec=prefetch steps_per_s={vec:.1f}"
        )
    print(f"train_steps_per_s={sps:.1f}")


if __name__ == "__main__":
    main()
