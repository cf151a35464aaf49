"""How closely the detectors' observation grid follows the ground truth, by distance ahead.

Drives the track planner (ground truth, ``--planner-sight-m`` of sight, planning again at every
step; the expert the OffroadTrack-v0 clones learn from) through ``--seeds`` courses of ``--env`` in
two envs at once: one with the detector grid (the env's default observation: the LiDAR rig cast
every step, paper N's negative cells and paper T's obstacle cells) and one with the oracle grid
without a range limit. Both get the planner's actions, so both drive the same path (checked each
step). Each step, each obstacle channel of the observation grid (pooled as the policy sees it)
is compared cell by cell in bands of ``--band-m`` metres ahead of the vehicle origin:
``recall`` = share of the oracle's cells the detector grid also sets, ``precision`` = share of
the detector grid's cells the oracle sets. A policy cloned on the oracle grid meets the
difference only when it is evaluated on the detector grid.

Cell counts weigh an obstacle by its area: a 4 x 3 m mound (a smooth bump of the heightfield that
neither detector calls an obstacle) outweighs a dozen rocks. So positive obstacles are also counted
one by one: at each step, each obstacle whose footprint reaches into the grid, binned by the
distance of its nearest footprint corner ahead, is *seen* when the detector grid sets at least one
of the pooled cells its footprint covers; one line per kind and band.

The ``traversable`` channel (paper T's region minus obstacles and their shadows; the oracle's: the
track's cells in view without an obstacle) is compared the same way: its precision is the share
of the cells the detector calls free that are.

Prints one line per course, one per channel and band, one per positive kind and band, then, last,
``negative_recall_4_14=<r> positive_recall_4_14=<r> traversable_recall_4_14=<r>
traversable_precision_4_14=<p> rock_box_seen_4_14=<r>`` (cells, and rocks and boxes, from 4 to 14 m
ahead, pooled over all steps).

``--positive-detector structure`` fills the detector grid's ``positive`` channel from paper N's rig
(returns above its ground map, ``ObservationConfig.positive_detector``) instead of paper T's LUX;
``--positive-hold-s S`` keeps its obstacle points on the grid for S seconds after the rig last saw
them (``ObservationConfig.positive_hold_s``; 0, the default, is per frame). ``--set`` changes any
setting of the env's scenario (``observation.lux_ego_motion=true``: paper T's boundary filters move
with the pose, ``ObservationConfig.lux_ego_motion``).

Run: python studies/grid_agreement.py [--seeds 5] [--first-seed 1000000]
[--env negobs_gym/OffroadTrack-v0] [--band-m 2] [--planner-sight-m 14] [--planner-horizon-m 30]
[--positive-detector traversable|structure] [--positive-hold-s 0] [--set observation.lux_ego_motion=true]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from negobs_gym.cli.common import add_set_option, task_env_or_exit
from negobs_gym.core.pose import Pose
from negobs_gym.detector import convex_overlap_mask
from negobs_gym.drivers import make_driver
from negobs_gym.spec import POSITIVE_DETECTORS

OBSTACLE_CHANNELS = ("negative", "positive")
# the oracle's traversable channel: on the track, no obstacle, in view (envs/observation.py)
COMPARED_CHANNELS = (*OBSTACLE_CHANNELS, "traversable")
# to 14 m: OffroadNav-v1/-v2's oracle range; from 4 m: nearer, the LUX's layers pass over a low rock
SUMMARY_BAND_M = (4.0, 14.0)


def twin(env: object, **observation: object) -> object:
    """An env like ``env`` (same scenario) with these observation fields changed."""
    raw = env.unwrapped
    return type(raw)(scenario=raw.scenario, overrides={f"observation.{k}": v for k, v in observation.items()})


def row_distances_m(env: object) -> np.ndarray:
    """Forward distance of each observation-grid row's centre from the vehicle origin [m] (row 0
    is the rearmost)."""
    observation = env.unwrapped.scenario.observation
    cell_m = observation.grid.cell_m * observation.downsample
    rows = observation.grid.rows // observation.downsample
    return -observation.grid.back_m + (np.arange(rows) + 0.5) * cell_m


def obstacles_in_view(env: object, pose: Pose) -> list[tuple[str, float, np.ndarray]]:
    """(kind, distance of the nearest footprint corner ahead [m], pooled cells its footprint covers)
    of each positive obstacle whose footprint reaches into the observation grid at ``pose``."""
    raw = env.unwrapped
    observation = raw.scenario.observation
    grid, k = observation.grid, observation.downsample
    x_min, x_max, y_min, y_max = grid.extent_xy_m
    found = []
    for obstacle in raw.terrain.positive_obstacles:
        corners = np.asarray(obstacle.footprint_xy_m)
        local = pose.to_vehicle(np.c_[corners, np.zeros(len(corners))])[:, :2]
        if (local[:, 0].max() < x_min or local[:, 0].min() > x_max) or (
            local[:, 1].max() < y_min or local[:, 1].min() > y_max
        ):
            continue
        fine = convex_overlap_mask(local, grid)
        pooled = fine.reshape(grid.rows // k, k, grid.cols // k, k).any(axis=(1, 3))
        if pooled.any():
            found.append((obstacle.kind, float(local[:, 1].min()), pooled))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="courses")
    parser.add_argument("--first-seed", type=int, default=1_000_000)
    parser.add_argument("--env", default="negobs_gym/OffroadTrack-v0")
    parser.add_argument("--band-m", type=float, default=2.0, help="width of a distance band")
    parser.add_argument("--planner-sight-m", type=float, default=14.0)
    parser.add_argument("--planner-horizon-m", type=float, default=30.0)
    parser.add_argument(
        "--positive-detector",
        choices=POSITIVE_DETECTORS,
        default="traversable",
        help="what fills the detector grid's positive channel (ObservationConfig.positive_detector)",
    )
    parser.add_argument(
        "--positive-hold-s",
        type=float,
        default=0.0,
        help="keep positive obstacles this long on the detector grid (ObservationConfig.positive_hold_s)",
    )
    add_set_option(parser)
    args = parser.parse_args()
    if args.seeds < 1 or not args.band_m > 0 or not args.positive_hold_s >= 0:
        parser.error("--seeds must be >= 1, --band-m > 0 and --positive-hold-s >= 0")

    named = task_env_or_exit(parser, args.env, "detector", args.overrides)
    detector_env = twin(named, positive_detector=args.positive_detector, positive_hold_s=args.positive_hold_s)
    named.close()
    oracle_env = twin(detector_env, source="oracle", oracle_range_m=None)
    channels = detector_env.unwrapped.scenario.observation.channels
    compared = [(channels.index(c), c) for c in COMPARED_CHANNELS if c in channels]
    if not any(c in channels for c in OBSTACLE_CHANNELS):
        parser.error(f"{args.env}'s grid has no obstacle channel ({', '.join(OBSTACLE_CHANNELS)})")
    distance = row_distances_m(detector_env)
    # oracle cells, detector cells, cells in both: per channel and grid row, summed over all steps
    counts = np.zeros((len(compared), 3, distance.size), dtype=np.int64)
    positive = channels.index("positive") if "positive" in channels else None
    sightings: list[tuple[str, float, bool]] = []  # (kind, distance ahead, seen) per obstacle and step
    begin = time.perf_counter()
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        det_obs, _ = detector_env.reset(seed=seed)
        obs, info = oracle_env.reset(seed=seed)
        driver = make_driver(
            "track_planner",
            oracle_env.terrain,
            planner_sight_m=args.planner_sight_m,
            planner_horizon_m=args.planner_horizon_m,
        )
        done, steps = False, 0
        while not done:
            for k, (index, _) in enumerate(compared):
                truth, seen = obs["grid"][index] > 0, det_obs["grid"][index] > 0
                counts[k] += np.stack([truth.sum(1), seen.sum(1), (truth & seen).sum(1)])
            if positive is not None:
                marked = det_obs["grid"][positive] > 0
                for kind, ahead_m, cells in obstacles_in_view(oracle_env, Pose.from_array(info["pose"])):
                    sightings.append((kind, ahead_m, bool((marked & cells).any())))
            action = driver.act(obs, info)
            obs, _, terminated, truncated, info = oracle_env.step(action)
            det_obs, _, _, _, det_info = detector_env.step(action)
            if det_info["station_m"] != info["station_m"]:
                raise RuntimeError(f"seed {seed}: the two envs' drives parted at step {steps}")
            done, steps = terminated or truncated, steps + 1
        end = "+".join(info["termination"]) or "time_limit"
        print(f"seed={seed} steps={steps} end={end} station_m={info['station_m']:.1f}", flush=True)
    detector_env.close()
    oracle_env.close()

    first, last = np.floor(distance[0] / args.band_m), np.ceil(distance[-1] / args.band_m)
    edges = np.arange(first, last + 1) * args.band_m
    band = np.digitize(distance, edges) - 1
    summary = {}
    for k, (_, name) in enumerate(compared):
        for b in range(edges.size - 1):
            truth, seen, both = counts[k][:, band == b].sum(1)
            if truth == 0 and seen == 0:
                continue
            recall = f"{both / truth:.2f}" if truth else "-"
            precision = f"{both / seen:.2f}" if seen else "-"
            print(
                f"{name} {edges[b]:+5.1f}..{edges[b + 1]:+5.1f} m: oracle_cells={truth} "
                f"detector_cells={seen} recall={recall} precision={precision}"
            )
        rows = (distance >= SUMMARY_BAND_M[0]) & (distance < SUMMARY_BAND_M[1])
        truth, seen, both = counts[k][:, rows].sum(1)
        summary[f"{name}_recall_4_14"] = both / truth if truth else float("nan")
        if name == "traversable":  # free space claimed where the truth has none matters here
            summary[f"{name}_precision_4_14"] = both / seen if seen else float("nan")
    kinds = np.array([kind for kind, _, _ in sightings], dtype=str)
    ahead = np.array([d for _, d, _ in sightings], dtype=float)
    hit = np.array([seen for _, _, seen in sightings], dtype=bool)
    for kind in sorted(set(kinds.tolist())):
        for b in range(edges.size - 1):
            sel = (kinds == kind) & (ahead >= edges[b]) & (ahead < edges[b + 1])
            if sel.any():
                print(
                    f"positive objects {kind} {edges[b]:+5.1f}..{edges[b + 1]:+5.1f} m: "
                    f"sightings={sel.sum()} seen={hit[sel].mean():.2f}"
                )
    solid = np.isin(kinds, ("rock", "box")) & (ahead >= SUMMARY_BAND_M[0]) & (ahead < SUMMARY_BAND_M[1])
    summary_objects = f"{hit[solid].mean():.2f}" if solid.any() else "-"
    print(f"wall_s={time.perf_counter() - begin:.0f}")
    print(
        " ".join(f"{name}={value:.2f}" for name, value in summary.items())
        + f" rock_box_seen_4_14={summary_objects}"
    )


if __name__ == "__main__":
    main()
