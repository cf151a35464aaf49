"""How much of a cloning recipe's result is the recipe and how much the fit's seed.

Fits a fresh policy on a saved ``demonstrations.npz`` (``negobs train --demonstrations FILE``,
mirrored) once per fit seed, evaluates each clone on the same unseen OffroadTrack-v0 courses
(``negobs eval policy``'s seeds 1,000,000 on, oracle grid, no filter) and prints one line per
seed, then the mean and standard deviation of the goals. One 60-seed evaluation of one fit tells
two recipes apart only when they differ by more than the spread between fit seeds, which on the
clones so far reaches 10 goals of 100 (docs/notebook/training_studies.md, "Weighting the passes").

Each fit writes ``OUT/fit_<seed>/`` (``train.json``, ``warm_start.zip``) and its evaluation
``OUT/eval_<seed>/``. A fit or an evaluation already there is read back, not run again, if its
recorded settings are the ones asked for (else the script stops and names the difference).
A fit of 40,000 mirrored steps takes 5-10 min on the 2 cores, its 60-seed evaluation 2-3 min.

Run: python studies/refit_seeds.py DEMOS.npz --out DIR [--fit-seeds 1 2 3]
[--strong-steer-repeats 1] [--strong-steer 0.3] [--steering-modes K] [--steering-bins EDGE ...]
[--eval-seeds 60] [--first-seed 1000000] [--workers 2] [--env negobs_gym/OffroadTrack-v0]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
from pathlib import Path

from negobs_gym.eval.campaign import Backend, RunOptions
from negobs_gym.eval.policy_campaign import PolicyCampaignConfig, run_policy_campaign
from negobs_gym.policies.config import SteeringHeadConfig, TrainConfig, WarmStartConfig, steering_head
from negobs_gym.policies.training import train


def fit(demos: str, seed: int, args: argparse.Namespace, out: Path) -> Path:
    """A fresh clone fitted on ``demos`` with ``seed``; the path of its ``warm_start.zip``."""
    model = out / "warm_start.zip"
    config = TrainConfig(
        env=args.env,
        source="oracle",
        steps=64,  # the clone is the warm start: PPO's one short rollout after it is not used
        envs=1,
        n_steps=64,
        batch_size=64,
        eval_every=0,
        eval_episodes=1,
        checkpoint_every=0,
        seed=seed,
        progress=False,
        head=steering_head(args.steering_modes, args.steering_bins),
        warm_start=WarmStartConfig(
            demonstrations=demos,
            mirror=True,
            strong_steer=args.strong_steer,
            strong_steer_repeats=args.strong_steer_repeats,
        ),
    )
    if model.exists():
        recorded = json.loads((out / "train.json").read_text(encoding="utf-8"))["config"]
        _same(_as_json(config), recorded, out / "train.json", _as_json(TrainConfig()))
        return model
    train(config, out)
    return model


def _as_json(config: object) -> dict:
    """A config as its JSON record reads back."""
    return json.loads(json.dumps(dataclasses.asdict(config)))


def _same(asked: dict, recorded: dict, path: Path, defaults: dict) -> None:
    """Stop if a result read back was made with other settings than the ones asked for (a setting
    that a record written before it existed lacks had its default)."""
    differ = {
        k: (recorded.get(k, defaults.get(k)), v)
        for k, v in asked.items()
        if recorded.get(k, defaults.get(k)) != v
    }
    if differ:
        raise SystemExit(f"{path} was made with other settings (recorded, asked): {differ}")


def evaluate(model: Path, args: argparse.Namespace, out: Path) -> dict[str, float]:
    """The clone's summary on ``args.eval_seeds`` unseen courses (filter off)."""
    config = PolicyCampaignConfig(
        model_path=str(model),
        env_id=args.env,
        seeds=args.eval_seeds,
        first_seed=args.first_seed,
        filters=(False,),
        source="oracle",
    )
    summary = out / "summary.json"
    if summary.exists():
        recorded = json.loads(summary.read_text(encoding="utf-8"))
        asked = {k: v for k, v in _as_json(config).items() if k != "model_path"}
        _same(asked, recorded["config"], summary, {})
        return recorded["summary"]["nofilter"]
    options = RunOptions(backend=Backend(workers=args.workers), progress=False)
    return run_policy_campaign(config, out, options)[2]["nofilter"]


def _count(summary: dict, key: str) -> str:
    """A summed count, or ``n/a`` in a summary written before the count existed."""
    return str(int(summary[key])) if key in summary else "n/a"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("demonstrations", help="a run's OUT/demonstrations.npz")
    parser.add_argument("--out", required=True, help="folder for the fits and their evaluations")
    parser.add_argument("--fit-seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--strong-steer-repeats", type=int, default=1)
    parser.add_argument("--strong-steer", type=float, default=WarmStartConfig().strong_steer)
    parser.add_argument("--steering-modes", type=int, default=SteeringHeadConfig().modes)
    parser.add_argument("--steering-bins", type=float, nargs="+", default=[])
    parser.add_argument("--eval-seeds", type=int, default=60)
    parser.add_argument("--first-seed", type=int, default=PolicyCampaignConfig.first_seed)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--env", default="negobs_gym/OffroadTrack-v0")
    args = parser.parse_args()
    out = Path(args.out)
    goals = []
    for seed in args.fit_seeds:
        model = fit(args.demonstrations, seed, args, out / f"fit_{seed}")
        s = evaluate(model, args, out / f"eval_{seed}")
        goals.append(s["goals"])
        n = int(s["episodes"])
        print(
            f"fit_seed={seed} goal={int(s['goals'])}/{n} entries={int(s['entries'])} "
            f"collisions={int(s['collisions'])} left_track={_count(s, 'left_track')} "
            f"mean_progress_m={s['mean_progress_m']:.1f}",
            flush=True,
        )
    sd = statistics.stdev(goals) if len(goals) > 1 else float("nan")
    print(f"fits={len(goals)} goal_mean={statistics.mean(goals):.1f} goal_sd={sd:.1f}")


if __name__ == "__main__":
    main()
