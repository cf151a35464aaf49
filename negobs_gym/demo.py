"""Quick-start demo: brake for a ditch at 25 km/h and draw the drive from above.

Builds the braking preset (a straight track with a ditch ``--ditch-distance`` metres ahead), drives
the vehicle at 25 km/h, applies a full brake ``--brake-before`` metres before the ditch, logs the stop
distance and the margin left to the ditch, and writes a top-down PNG with the driven path.

Run: ``python -m negobs_gym [--out outputs/demo.png] [--seed 0] [--ditch-distance 30]``
"""

from __future__ import annotations

import argparse
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.sim import presets
from negobs_gym.sim.events import EventMonitor
from negobs_gym.sim.render import render_top_down
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World, WorldConfig

log = logging.getLogger("negobs_gym.demo")

DEMO_SPEED_MPS = 25.0 / 3.6  # paper N §4: the ALV's test speed, 25 km/h


@dataclass(frozen=True)
class BrakingDemoResult:
    """Outcome of :func:`run_braking_demo`; distances in metres along the track."""

    brake_station_m: float  # where the brake was applied (vehicle front bumper)
    brake_speed_mps: float  # speed when the brake was applied
    stop_distance_m: float  # distance driven from brake application to standstill
    margin_m: float  # gap left between the front bumper and the ditch's near edge
    entered_ditch: bool
    path_xy_m: np.ndarray
    final_pose: Pose
    image_path: Path | None


def run_braking_demo(
    *,
    out_path: str | Path | None = "outputs/demo.png",
    seed: int = 0,
    ditch_distance_m: float = 30.0,
    brake_before_m: float = 15.0,
    speed_mps: float = DEMO_SPEED_MPS,
    max_time_s: float = 30.0,
) -> BrakingDemoResult:
    """Drive the braking preset and brake in front of the ditch (see module docstring).

    ``ditch_distance_m`` is measured from the start of the track to the ditch's near edge; the
    brake goes on when the front bumper is ``brake_before_m`` from that edge.
    """
    if not (math.isfinite(ditch_distance_m) and ditch_distance_m > brake_before_m + 5.0):
        raise ValueError(
            f"ditch_distance_m must exceed brake_before_m + 5 m = {brake_before_m + 5.0}, "
            f"got {ditch_distance_m}"
        )
    terrain = presets.braking_track(ditch_distance_m=ditch_distance_m, seed=seed)
    ditch = terrain.negative_obstacles[0]
    world_config = WorldConfig()
    with World(terrain, world_config) as world:
        vehicle = Vehicle(world)
        monitor = EventMonitor(world, vehicle)
        front_m = vehicle.config.length_m - vehicle.config.rear_overhang_m  # rear axle -> front bumper
        start = np.asarray(terrain.start_xy_yaw[:2])
        heading = Pose(yaw=terrain.start_xy_yaw[2]).heading
        near_edge_m = float(np.min((np.asarray(ditch.outline_xy_m) - start) @ heading))
        world.step(round(0.5 / world_config.time_step_s))  # let the suspension settle
        vehicle.set_speed(speed_mps)
        vehicle.apply(0.0, 0.0, 0.0)
        path = []
        brake_station = None
        brake_speed = math.nan
        steps_per_sample = max(1, round(0.05 / world_config.time_step_s))
        for _ in range(round(max_time_s / (steps_per_sample * world_config.time_step_s))):
            pose = vehicle.true_pose()
            path.append((pose.x, pose.y))
            station = float((np.array([pose.x, pose.y]) - start) @ heading)
            if brake_station is None and station + front_m >= near_edge_m - brake_before_m:
                brake_station = station
                brake_speed = vehicle.speed_mps()
                vehicle.apply(0.0, 1.0, 0.0)
            elif brake_station is None:
                # hold the speed until the brake point (a simple proportional cruise control)
                vehicle.apply(float(np.clip(5.0 * (speed_mps - vehicle.speed_mps()), 0.0, 1.0)), 0.0, 0.0)
            world.step(steps_per_sample)
            if brake_station is not None and abs(vehicle.speed_mps()) < 0.01:
                break
        final = vehicle.true_pose()
        path.append((final.x, final.y))
        events = monitor.poll()
    if brake_station is None:
        raise RuntimeError("the vehicle never reached the brake point; increase max_time_s")
    final_station = float((np.array([final.x, final.y]) - start) @ heading)
    result_path = np.asarray(path)
    image = None
    if out_path is not None:
        image = Path(out_path)
        image.parent.mkdir(parents=True, exist_ok=True)
        render_top_down(terrain, path_xy_m=result_path, vehicle_pose=final, out_path=image)
    return BrakingDemoResult(
        brake_station_m=brake_station + front_m,
        brake_speed_mps=brake_speed,
        stop_distance_m=final_station - brake_station,
        margin_m=near_edge_m - (final_station + front_m),
        entered_ditch=ditch.obstacle_id in monitor.entered_ids or bool(events.entered_negative_obstacle),
        path_xy_m=result_path,
        final_pose=final,
        image_path=image,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point of ``python -m negobs_gym``."""
    parser = argparse.ArgumentParser(prog="python -m negobs_gym", description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="outputs/demo.png", help="PNG to write (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="terrain seed (default: %(default)s)")
    parser.add_argument(
        "--ditch-distance",
        type=float,
        default=30.0,
        help="start to the ditch's near edge [m] (default: %(default)s)",
    )
    parser.add_argument(
        "--brake-before",
        type=float,
        default=15.0,
        help="brake this far before the ditch [m] (default: %(default)s)",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        result = run_braking_demo(
            out_path=args.out,
            seed=args.seed,
            ditch_distance_m=args.ditch_distance,
            brake_before_m=args.brake_before,
        )
    except ValueError as exc:
        parser.error(str(exc))
    log.info("full brake at 25 km/h, %.1f m before the ditch", args.brake_before)
    ideal = result.brake_speed_mps**2 / (2 * 0.65 * 9.81)
    log.info(
        "speed at the brake point %.2f m/s; stop distance %.2f m (flat-ground v^2/(2 mu g) = %.2f m)",
        result.brake_speed_mps,
        result.stop_distance_m,
        ideal,
    )
    log.info("margin to the ditch: %.2f m; entered the ditch: %s", result.margin_m, result.entered_ditch)
    log.info("wrote %s", result.image_path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
