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
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from negobs_gym.drivers import RecklessDriver
from negobs_gym.envs.scenarios import BrakingEnv
from negobs_gym.safety import BrakingSafetyFilter
from negobs_gym.sim.render import write_png_atomic

log = logging.getLogger("negobs_gym.demo")

STANDSTILL_MPS = 0.1  # the run ends after STANDSTILL_S below this speed
STANDSTILL_S = 1.0


@dataclass(frozen=True)
class DemoRun:
    """One episode of the demo; distances in metres from the front bumper to the ditch."""

    filtered: bool
    start_gap_m: float  # ditch distance at the start
    entered_ditch: bool
    final_gap_m: float  # gap left at the end (inf once the bumper is past the ditch's near edge)
    final_speed_mps: float
    first_veto_gap_m: float | None  # gap when the filter first braked (None: never)
    vetoes: int
    steps: int
    frame: np.ndarray  # final rgb_array frame


def run_episode(seed: int, filtered: bool) -> DemoRun:
    """Drive one reckless episode of Braking-v1, optionally behind the safety filter."""
    env: gym.Env = BrakingEnv(render_mode="rgb_array")
    if filtered:
        env = BrakingSafetyFilter(env)
    driver = RecklessDriver()
    driver.reset(seed)
    obs, info = env.reset(seed=seed)
    start_gap = float(info["distance_to_negative_ahead_m"])
    dt = 1.0 / env.unwrapped.scenario.episode.control_hz
    first_veto, vetoes, still_s, steps = None, 0, 0.0, 0
    done = False
    while not done:
        gap = float(info["distance_to_negative_ahead_m"])
        obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
        steps += 1
        if filtered and info["safety"]["vetoed"]:
            vetoes += 1
            first_veto = gap if first_veto is None else first_veto
        still_s = still_s + dt if info["speed_mps"] < STANDSTILL_MPS else 0.0
        done = terminated or truncated or still_s >= STANDSTILL_S  # v1 itself ends after 1 s standing
    frame = env.render()
    env.close()
    return DemoRun(
        filtered=filtered,
        start_gap_m=start_gap,
        entered_ditch=bool(info["events"]["entered_negative_obstacle"]),
        final_gap_m=float(info["distance_to_negative_ahead_m"]),
        final_speed_mps=float(info["speed_mps"]),
        first_veto_gap_m=first_veto,
        vetoes=vetoes,
        steps=steps,
        frame=frame,
    )


def write_figure(runs: Sequence[DemoRun], out_path: Path) -> Path:
    """Final frames side by side with their outcome as titles; written atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(runs), figsize=(6 * len(runs), 6.5), squeeze=False)
    for ax, run in zip(axes[0], runs, strict=True):
        ax.imshow(run.frame)
        ax.set_axis_off()
        outcome = "entered the ditch" if run.entered_ditch else f"stopped {run.final_gap_m:.1f} m before it"
        name = "with safety filter" if run.filtered else "no filter"
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
    log.info("Braking-v1, seed %d: ditch %.1f m ahead of the bumper, 25 km/h", seed, runs[0].start_gap_m)
    for run in runs:
        name = "with safety filter" if run.filtered else "no filter"
        if run.entered_ditch:
            log.info("  %-18s entered the ditch after %d steps", name, run.steps)
        else:
            log.info(
                "  %-18s stopped %.2f m before the ditch; first brake at %.1f m, %d vetoed steps",
                name,
                run.final_gap_m,
                run.first_veto_gap_m if run.first_veto_gap_m is not None else float("nan"),
                run.vetoes,
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
