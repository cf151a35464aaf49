"""Learning curves of ``negobs train`` runs: episode return and evaluation goal share per env step.

Run: python studies/learning_curves.py LABEL=RUN_DIR [LABEL=RUN_DIR ...] --out curves.png

Each RUN_DIR is a ``negobs train --out`` folder (``logs/*/progress.csv``, ``eval.csv``). Prints,
per run, the last logged return and each evaluation's goal share.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

from negobs_gym.eval.plots import learning_curves_plot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", metavar="LABEL=RUN_DIR")
    parser.add_argument("--out", type=Path, default=Path("learning_curves.png"))
    args = parser.parse_args()
    runs = dict(item.split("=", 1) for item in args.runs)
    for label, folder in runs.items():
        evaluation = Path(folder) / "eval.csv"
        rows = list(csv.DictReader(evaluation.open(newline=""))) if evaluation.exists() else []
        goals = ", ".join(f"{r['step']}: {r['goal']}/{r['episodes']}" for r in rows) or "none"
        print(f"{label}: evaluations (step: goal) {goals}")
    print(f"wrote {learning_curves_plot(runs, args.out)}")


if __name__ == "__main__":
    main()
