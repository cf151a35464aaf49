"""End-to-end PPO training rate per vector env: where a `negobs train` run's time goes.

Run: ``python benchmarks/train_rate.py [--steps 4096] [--rounds 2] [--vec-env subproc --vec-env build_ahead]
[--env negobs_gym/OffroadNav-v1] [--source oracle] [--envs 2] [--n-steps 512] [--batch-size 128]
[--set KEY=VALUE]``

Each round trains a fresh PPO model (seed 0, no evaluation but the final one-episode check, no
checkpoints) once per vector env, the vector envs alternating, so a slow phase of the machine
hits each about equally. Printed per run: ``session_steps_per_s`` (``train.json``'s: rollouts,
updates, resets and the final evaluation), the seconds spent collecting rollouts and in PPO's
updates, and the workers' world counts (``misses``: resets that built their world, ``ahead_hits``:
resets that found it built ahead). The last line is ``<vec_env>_over_<first>=<ratio>`` of the
mean rates, for each vector env after the first.

``--set KEY=VALUE`` (repeatable, as ``negobs train --set``) adds, in every round and for every
vector env, a run on the scenario with those settings right after the run without them, and
prints ``set_over_base=<ratio>`` of their mean rates last (e.g. ``--source detector --set
observation.scan_every=2``: a LiDAR frame every other step).
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import tempfile
from collections import Counter

from env_step import StageTimer  # this directory's benchmark
from stable_baselines3 import PPO
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.vec_env import SubprocVecEnv

from negobs_gym.envs.vector import PrefetchVecEnv
from negobs_gym.policies.config import VEC_ENVS, TrainConfig
from negobs_gym.policies.training import train
from negobs_gym.scenarios import env_with_overrides


def _count_worlds_at_close(owner: type, counts: Counter) -> None:
    """Make ``owner.close`` first add its workers' world-cache counters to ``counts``."""
    close = owner.close

    def counting_close(self) -> None:
        if not self.closed:
            for worker in self.env_method("world_cache_counts"):
                counts.update(worker)
        close(self)

    owner.close = counting_close


def run_once(config: TrainConfig) -> dict[str, float]:
    """Train ``config`` into a temporary folder; its rate, stage seconds and world counts."""
    counts: Counter = Counter()
    closes = {cls: cls.close for cls in (SubprocVecEnv, PrefetchVecEnv)}
    with StageTimer() as timer, tempfile.TemporaryDirectory() as out:
        timer.wrap(OnPolicyAlgorithm, "collect_rollouts", "collect")
        timer.wrap(PPO, "train", "update")
        for cls in closes:
            _count_worlds_at_close(cls, counts)
        try:
            result = train(config, out)
        finally:
            for cls, close in closes.items():
                cls.close = close
    return {
        "session_steps_per_s": result.steps_per_s,
        "collect_s": timer.total_s["collect"],
        "update_s": timer.total_s["update"],
        "misses": counts["misses"],
        "ahead_hits": counts["ahead_hits"],
        "hits": counts["hits"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4096, help="env steps per run")
    parser.add_argument("--rounds", type=int, default=2, help="runs per vector env")
    parser.add_argument(
        "--vec-env", action="append", choices=VEC_ENVS, help="repeatable; default subproc, build_ahead"
    )
    parser.add_argument("--env", default="negobs_gym/OffroadNav-v1")
    parser.add_argument("--source", default="oracle")
    parser.add_argument("--envs", type=int, default=2)
    parser.add_argument("--n-steps", type=int, default=512)
    parser.add_argument("--batch-size", type=int, default=128)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    if args.steps < 1 or args.rounds < 1 or args.envs < 2:
        parser.error("--steps and --rounds must be >= 1, --envs >= 2 (a vector env of processes)")
    vec_envs = args.vec_env or ["subproc", "build_ahead"]
    with tempfile.TemporaryDirectory() as scenario_dir:
        rates = run_rounds(args, vec_envs, scenario_dir)
    mean = {key: statistics.fmean(r) for key, r in rates.items()}
    first = vec_envs[0]
    for (name, variant), rate in mean.items():
        print(f"vec_env={name} variant={variant} mean_session_steps_per_s={rate:.1f}")
    for name in vec_envs[1:]:
        print(f"{name}_over_{first}={mean[name, 'base'] / mean[first, 'base']:.3f}")
    if args.overrides:
        print(f"set_over_base={statistics.fmean(mean[n, 'set'] / mean[n, 'base'] for n in vec_envs):.3f}")


def run_rounds(
    args: argparse.Namespace, vec_envs: list[str], scenario_dir: str
) -> dict[tuple[str, str], list]:
    """``session_steps_per_s`` of every run by (vector env, ``base`` or ``set``), each printed."""
    variants = {"base": args.env}
    if args.overrides:
        variants["set"] = env_with_overrides(args.env, args.overrides, scenario_dir)
    rates: dict[tuple[str, str], list[float]] = {(n, v): [] for n in vec_envs for v in variants}
    for round_ in range(args.rounds):
        for name, (variant, env) in itertools.product(vec_envs, variants.items()):
            config = TrainConfig(
                env=env,
                source=args.source,
                steps=args.steps,
                envs=args.envs,
                vec_env=name,
                n_steps=args.n_steps,
                batch_size=args.batch_size,
                eval_every=0,
                eval_episodes=1,
                checkpoint_every=0,
                seed=0,
                progress=False,
            )
            got = run_once(config)
            rates[name, variant].append(got["session_steps_per_s"])
            figures = " ".join(f"{k}={v:.1f}" if isinstance(v, float) else f"{k}={v}" for k, v in got.items())
            label = f"{args.env} {' '.join(args.overrides)}" if variant == "set" else args.env
            print(f"round={round_} vec_env={name} env={label} source={args.source} {figures}", flush=True)
    return rates


if __name__ == "__main__":
    main()
