"""Physics speed on a 200 m course: terrain build time, physics steps/s and peak RSS.

Run: ``python benchmarks/sim_step.py [--length 200] [--physics-resolution 0.2] [--seconds 20]``

Also (``--renderer-builds N``): the world build of one course with PyBullet's software renderer
dropped (the default, ``WorldConfig.pybullet_renderer=False``) and kept, alternately, N times each
in this process: mean build and close seconds and the resident memory a kept world adds.
"""

from __future__ import annotations

import argparse
import dataclasses
import resource
import time

from negobs_gym.sim import presets
from negobs_gym.sim.events import EventMonitor
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World, WorldConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length", type=float, default=200.0, help="course length [m]")
    parser.add_argument("--physics-resolution", type=float, default=0.25, help="physics grid [m]")
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated drive [s]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resets", type=int, default=5, help="episode resets with a new winding course")
    parser.add_argument(
        "--renderer-builds", type=int, default=5, help="world builds with and without the renderer, each"
    )
    args = parser.parse_args()

    t0 = time.perf_counter()
    terrain = presets.rough_track(length_m=args.length, seed=args.seed)
    t_gen = time.perf_counter() - t0
    config = WorldConfig(physics_resolution_m=args.physics_resolution)
    t0 = time.perf_counter()
    world = World(terrain, config)
    t_build = time.perf_counter() - t0
    with world:
        vehicle = Vehicle(world)
        monitor = EventMonitor(world, vehicle)
        vehicle.set_speed(25 / 3.6)
        vehicle.apply(0.3, 0.0, 0.0)
        n = round(args.seconds / config.time_step_s)
        t0 = time.perf_counter()
        world.step(n)
        t_step = time.perf_counter() - t0
        events = monitor.poll()
    ny, nx = terrain.heightfield.shape
    pny, pnx = world.physics_heightfield.shape
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"terrain {nx}x{ny} at {terrain.heightfield.resolution_m} m, "
        f"physics {pnx}x{pny} at {args.physics_resolution} m"
    )
    print(f"terrain_generate_s={t_gen:.2f}")
    print(f"terrain_build_s={t_build:.2f}")
    print(f"physics_steps_per_s={n / t_step:.0f} (vehicle + event monitor, {n} steps)")
    print(f"realtime_factor={n * config.time_step_s / t_step:.1f}")
    print(f"events={events}")
    print(f"peak_rss_mb={rss_mb:.0f}")
    if args.resets > 0:
        reset_times = []
        for k in range(args.resets):
            # An episode reset with a new course: generate it, build a fresh world and vehicle.
            t0 = time.perf_counter()
            course = presets.winding_course(seed=args.seed + 1 + k, length_m=args.length)
            with World(course, config) as reset_world:
                Vehicle(reset_world)
                reset_world.step(1)
                reset_times.append(time.perf_counter() - t0)
        print(
            f"reset_new_course_s: mean={sum(reset_times) / len(reset_times):.2f} max={max(reset_times):.2f} "
            f"({args.resets} winding courses of {args.length:g} m)"
        )
        print(f"rss_after_resets_mb={current_rss_mb():.0f}")
        print(f"peak_rss_mb={resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f}")
    if args.renderer_builds > 0:
        _renderer_builds(terrain, config, args.renderer_builds)


def _renderer_builds(terrain, config: WorldConfig, n: int) -> None:
    """World build and close with PyBullet's software renderer dropped and kept, alternately."""
    stats: dict[bool, list[tuple[float, float, float]]] = {False: [], True: []}
    for k in range(2 * n):
        kept = bool(k % 2)
        rss0 = current_rss_mb()
        t0 = time.perf_counter()
        world = World(terrain, dataclasses.replace(config, pybullet_renderer=kept))
        t_build = time.perf_counter() - t0
        rss = current_rss_mb() - rss0
        t0 = time.perf_counter()
        world.close()
        stats[kept].append((t_build, time.perf_counter() - t0, rss))
    for kept, name in ((False, "dropped"), (True, "kept")):
        build, close, rss = (sum(col) / n for col in zip(*stats[kept], strict=True))
        print(
            f"world_build_renderer_{name}_s={build:.3f} close_s={close:.3f} world_rss_mb={rss:.0f} "
            f"({n} builds)"
        )


def current_rss_mb() -> float:
    """Resident set size of this process now [MB] (Linux /proc)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


if __name__ == "__main__":
    main()
