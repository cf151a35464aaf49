"""Safety: braking behind the safety filter at 25 km/h, and the car's full-brake stop.

The braking campaign of ``negobs eval braking`` (:mod:`negobs_gym.eval.braking_campaign`) runs
the reckless driver (full throttle up to 25 km/h, never brakes) behind the filter (paper N
Eq. 18) toward Braking-v0's ditch (1.0 m along the track, 3.0 m across, 0.8 m deep) and a narrow
trench (0.4 m along, 6 m across, 1.0 m deep); the filter reads the envs' default detector grid.
The physics figure is the full-brake stop from 25 km/h on flat ground (ideal v² / (2 mu g) =
3.78 m for mu = 0.65).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass

import numpy as np

from negobs_gym.bench.harness import BenchError, Figure, Figures, Suite, positive_counts
from negobs_gym.eval.braking_campaign import BrakingCampaignConfig, configuration_name, run_braking_campaign
from negobs_gym.eval.campaign import Backend, RunOptions
from negobs_gym.sim import presets
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

SCENARIOS = {"ditch": "Braking-v0's ditch", "trench_narrow": "a 0.4 m trench"}
WORKERS = 2  # campaign worker processes: the machine's 2 cores
SPEED_MPS = 25 / 3.6  # paper N §4: 25 km/h


@dataclass(frozen=True)
class SafetySize:
    """How many braking episodes run per scenario."""

    episodes: int

    def __post_init__(self) -> None:
        positive_counts(self)


def braking_campaign(size: SafetySize) -> Figures:
    """Share of episodes stopped before the obstacle and the median stop margin, per scenario."""
    config = BrakingCampaignConfig(
        seeds=size.episodes, scenarios=tuple(SCENARIOS), drivers=("reckless",), filters=(True,)
    )
    options = RunOptions(backend=Backend(workers=WORKERS), progress=False)
    with tempfile.TemporaryDirectory() as out:
        summaries = {s.name: s for s in run_braking_campaign(config, out, options).summaries}
    figures = {}
    for scenario, what in SCENARIOS.items():
        s = summaries[configuration_name(scenario, "reckless", True)]
        if not s.stop_margins_m:
            raise BenchError(f"safety: no episode stopped before {what}; no stop margin to report")
        figures[f"{scenario}_stopped_pct"] = Figure(
            100.0 * s.stopped_before / s.episodes,
            "%",
            f"stopped before {what} behind the filter ({s.episodes} runs)",
        )
        figures[f"{scenario}_margin_m"] = Figure(
            float(np.median(s.stop_margins_m)), "m", f"median stop margin before {what}"
        )
    return figures


def full_brake(size: SafetySize) -> Figures:
    """Distance from brake application at 25 km/h to standstill on flat ground."""
    with World(presets.braking_track(ditch_distance_m=40.0, seed=0, rough=False)) as world:
        vehicle = Vehicle(world)
        world.step(round(0.5 / world.config.time_step_s))  # settle
        start = vehicle.true_pose().translation[:2]
        vehicle.set_speed(SPEED_MPS)
        vehicle.apply(0.0, 1.0, 0.0)
        for _ in range(round(10.0 / world.config.time_step_s)):
            if vehicle.speed_mps() <= 0.01:
                break
            world.step()
        distance = float(np.linalg.norm(vehicle.true_pose().translation[:2] - start))
    return {
        "stop_distance_m": Figure(distance, "m", "full-brake stop from 25 km/h, flat ground (ideal 3.78 m)")
    }


SUITE = Suite(
    name="safety",
    what="braking safety",
    full=SafetySize(episodes=100),
    quick=SafetySize(episodes=3),
    measurements=(full_brake, braking_campaign),
)
