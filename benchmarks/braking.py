"""Full-brake stopping distance from 25 km/h on flat ground (physics part of paper N Eq. 18; docs/physics.md).

Settles the vehicle on a flat braking preset, sets 25 km/h, locks the wheels and measures the
distance to standstill. The ideal is v^2 / (2 mu g) = 3.78 m for mu = 0.65. The last line printed is
``stop_distance_m=<value>``.

Run: ``python benchmarks/braking.py [--speed-kmh 25] [--rate-hz 240] [--rough]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from negobs_gym.safety.braking import BrakingConfig
from negobs_gym.sim import presets
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World, WorldConfig


def stop_distance_m(speed_mps: float, time_step_s: float, rough: bool, seed: int) -> tuple[float, float]:
    """(distance [m], time [s]) from brake application to standstill."""
    terrain = presets.braking_track(ditch_distance_m=40.0, seed=seed, rough=rough)
    with World(terrain, WorldConfig(time_step_s=time_step_s)) as world:
        vehicle = Vehicle(world)
        world.step(round(0.5 / time_step_s))
        start = vehicle.true_pose().translation[:2]
        vehicle.set_speed(speed_mps)
        vehicle.apply(0.0, 1.0, 0.0)
        steps = 0
        while vehicle.speed_mps() > 0.01 and steps < round(10.0 / time_step_s):
            world.step()
            steps += 1
        return float(np.linalg.norm(vehicle.true_pose().translation[:2] - start)), steps * time_step_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed-kmh", type=float, default=25.0)
    parser.add_argument("--rate-hz", type=float, default=240.0, help="physics rate (240 or 120)")
    parser.add_argument("--rough", action="store_true", help="brake on the rough preset instead of flat")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--mu", type=float, default=BrakingConfig().mu, help="tyre mu for the ideal figure")
    args = parser.parse_args()
    speed = args.speed_kmh / 3.6
    ideal = speed**2 / (2 * args.mu * BrakingConfig().g_mps2)
    t0 = time.perf_counter()
    distance, duration = stop_distance_m(speed, 1.0 / args.rate_hz, args.rough, args.seed)
    wall = time.perf_counter() - t0
    print(f"speed_mps={speed:.3f} rate_hz={args.rate_hz:g} rough={args.rough}")
    print(f"ideal_m={ideal:.3f} (v^2 / (2 mu g), mu={args.mu})")
    print(f"stop_time_s={duration:.3f} wall_s={wall:.2f}")
    print(f"error_pct={100 * (distance - ideal) / ideal:+.1f}")
    print(f"stop_distance_m={distance:.3f}")


if __name__ == "__main__":
    main()
