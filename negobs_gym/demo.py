"""Quick-start demo: a reckless driver at 25 km/h towards a ditch, without and with the safety filter.

Runs ``negobs_gym/Braking-v1`` twice with the same seed (same terrain, same ditch 20-40 m ahead,
same sensor noise). The reckless driver holds full throttle and never brakes. The second run wraps
the env in :class:`~negobs_gym.safety.BrakingSafetyFilter`, which sees the ditch only through the
LiDAR detector grid (paper N's rig and detector) and brakes when the distance to it falls below
R(v) = v^2/(2 mu g) + v T_r + B (paper N Eq. 18). Logs both outcomes and writes the two final
top-down frames side by side to a PNG.

Run: ``python -m negobs_gym [--out outputs/demo.png] [--seed 0]``
"""

from __future__ import annotations

import argparse
import contextlib
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from negobs_gym.drivers import RecklessDriver
from negobs_gym.envs.scenarios import BrakingEnv
from negobs_gym.eval.episode import STANDSTILL_S, EpisodeResult, EpisodeStop, drive_episode
from negobs_gym.sim.render import write_png_atomic

log = logging.getLogger("negobs_gym.demo")

STOP = EpisodeStop(standstill_s=STANDSTILL_S)  # v1 itself ends after 1 s standing too


@dataclass(frozen=True)
class DemoRun:
    """One episode of the demo: what it did and its final top-down frame."""

    result: EpisodeResult
    frame: np.ndarray  # final rgb_array frame


def run_episode(seed: int, filtered: bool) -> DemoRun:
    """Drive one reckless episode of Braking-v1, optionally behind the safety filter."""
    with contextlib.closing(BrakingEnv(render_mode="rgb_array")) as env:
        result = drive_episode(env, RecklessDriver(), seed=seed, filter=filtered, stop=STOP)
        return DemoRun(result, env.render())


def write_figure(runs: Sequence[DemoRun], out_path: Path) -> Path:
    """Final frames side by side with their outcome as titles; written atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(runs), figsize=(6 * len(runs), 6.5), squeeze=False)
    for ax, run in zip(axes[0], runs, strict=True):
        ax.imshow(run.frame)
        ax.set_axis_off()
        r = run.result
        outcome = (
            "entered the ditch" if r.entered_negative_obstacle else f"stopped {r.final_gap_m:.1f} m before it"
        )
        name = "with safety filter" if r.filtered else "no filter"
        ax.set_title(f"reckless driver, {name}: {outcome}")
    fig.suptitle("Braking-v1: ditch seen only by the LiDAR detector grid, 25 km/h")
    fig.tight_layout()
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    write_png_atomic(image, out_path)
    return out_path


def run_demo(out_path: str | Path | None = "outputs/demo.png", seed: int = 0) -> list[DemoRun]:
    """Both runs (no filter, then filter) with the same seed; the figure when ``out_path`` is set."""
    runs = [run_episode(seed, filtered=False), run_episode(seed, filtered=True)]
    if out_path is not None:
        write_figure(runs, Path(out_path))
    return runs


def log_runs(runs: Sequence[DemoRun], seed: int, out_path: str | Path | None) -> None:
    """Log the outcome of both demo runs (and where the figure went)."""
    log.info(
        "Braking-v1, seed %d: ditch %.1f m ahead of the bumper, 25 km/h", seed, runs[0].result.start_gap_m
    )
    for r in (run.result for run in runs):
        name = "with safety filter" if r.filtered else "no filter"
        if r.entered_negative_obstacle:
            log.info("  %-18s entered the ditch after %d steps", name, r.steps)
        else:
            log.info(
                "  %-18s stopped %.2f m before the ditch; first brake at %.1f m, %d vetoed steps",
                name,
                r.final_gap_m,
                r.first_veto_gap_m if r.first_veto_gap_m is not None else float("nan"),
                r.vetoes,
            )
    if out_path is not None:
        log.info("wrote %s", out_path)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point of ``python -m negobs_gym`` (same as ``negobs demo``)."""
    parser = argparse.ArgumentParser(prog="python -m negobs_gym", description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="outputs/demo.png", help="PNG to write (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="episode seed (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    log_runs(run_demo(args.out, args.seed), args.seed, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
