"""Train PPO with the grid CNN on a negobs env: the library code behind ``negobs train``.

Run::

    python examples/train_ppo.py --env negobs_gym/Braking-v1 --steps 20000 --envs 2 --out outputs/ppo
    python examples/train_ppo.py --filter --source oracle ...   # behind the Eq. 18 safety filter

Every option of ``negobs train`` is accepted (``python examples/train_ppo.py --help``); the
algorithm is fixed to PPO here. The model is ``<out>/model.zip``; ``<out>/eval.csv`` holds the
evaluations on unseen seeds. Evaluate it again with ``negobs eval policy <out>/model.zip --env ID``.
"""

from __future__ import annotations

import argparse
import logging
import sys

from negobs_gym.cli import train as train_command
from negobs_gym.policies.training import train


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    subparsers = parser.add_subparsers(dest="command")
    train_command.register(subparsers)  # the same options as `negobs train`
    args = parser.parse_args(["train", *(sys.argv[1:] if argv is None else argv)])
    if args.algo != "PPO":
        parser.error("this example trains PPO; use `negobs train --algo SAC` for SAC")
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    result = train(train_command.config_from_args(args), args.out, resume=args.resume)
    logging.info(
        "saved %s after %d steps (%.1f steps/s); evaluations in %s",
        result.model_path,
        result.steps,
        result.steps_per_s,
        result.eval_csv,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
