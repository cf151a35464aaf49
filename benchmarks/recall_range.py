"""Benchmark: recall of paper N's detector against range, per sensor mode (paper N Table 7, Fig. 16).

Drives at 25 km/h toward one pit of each of paper N's four sizes (100x50, 100x80, 150x60,
100x100 cm, 0.8 m deep, straight ahead) on the rough braking track, for ``--seeds`` terrain/noise
seeds, sensor noise on. Every frame's scans go to three detectors (fused, HDL-64 only, HDL-32 only,
paper N Fig. 16) that each keep their own history. A frame counts as recalled in a mode when one
of its detected obstacles overlaps the pit on the 20 cm grid (``negobs_gym.eval.match_frame``);
frames are binned by the distance from the vehicle origin (the INS centre) to the centre of the
pit's cells, paper N §4.2's distance (``negobs_gym.eval.RecallTable``, one size bin;
``--bin-by nearest`` bins by the pit's nearest cell instead, which reads each bin ~0.5 m closer).
Prints the table, then ``fused_recall_12_20=<mean of the 12-20 m bins>`` and, last,
``fig16_order=<ok|violated>`` (ok: HDL-32 only >= HDL-64 only in every bin beyond 14 m).

``--rig roi`` is the envs' default training observation: paper N's native rig cast only where
the observation grid (and the features' neighbourhoods) need it (:mod:`negobs_gym.sensors.roi`),
the rays outside left as no return; its table is compared bin by bin with ``native``'s.

Also prints how far the fused detection's outline starts before the pit's near rim (the mean
over the recalled frames of each bin, along the track; a pit confirmed far out keeps its far
frames' early edge unless ``--tighten``, ``FusionConfig.tighten_on_match``) and
``near_edge_lead_6_12_m=``, its mean over 6-12 m, where the safety filter stops.

``--scan-every 1,2,3`` also evaluates the envs' ``ObservationConfig.scan_every``: the detectors
get every k-th frame only, and the frames between are judged on the last detection's outlines
carried from its INS pose to theirs (as the envs carry their grid). After the main table's lines
come, per further k, its table, its fused false alarms per frame and
``scan_every_<k>_max_drop=`` (the largest fused recall drop against the first k, 6-20 m bins).

``--cache DIR`` keeps the cast scans (float32 ranges + poses, one ``.npz`` per drive) so a second
run with another detector skips the ray casting (the cast dominates: ~0.3 s per frame).

Run: python benchmarks/recall_range.py [--seeds 8] [--rig native|roi|reduced] [--cache DIR]
     [--bin-by centre|nearest] [--tighten] [--scan-every 1,2,3]
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import os
import tempfile
from pathlib import Path

import numpy as np

from negobs_gym.core.grid import GridSpec, carry_points
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector import SENSOR_MODES, FusionConfig, NegativeDetectorConfig, NegativeObstacleDetector
from negobs_gym.detector.grid import convex_overlap_mask
from negobs_gym.spec import ObservationConfig
from negobs_gym.eval import DetectionEvalConfig, RecallTable, match_frame, world_outline_to_vehicle
from negobs_gym.sensors.lidar import scan_rig
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.rigs import Rig, paper_n_rig, paper_n_rig_reduced
from negobs_gym.sensors.roi import HeightEnvelope, RoiConfig, RoiSelector
from negobs_gym.sim.carving import PAPER_N_PIT_SIZES_M
from negobs_gym.sim.presets import braking_track
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

SPEED_MPS = 25 / 3.6  # paper N §4.2: 25 km/h
PIT_DEPTH_M = 0.8
PIT_START_M = 24.0  # near rim ahead of the start: a few frames of history before the 20 m bin
NEAREST_M = 6.0  # stop once the pit is this close (Table 7's first bin starts at 6 m)
FRAME_S = 0.1  # 10 Hz
RIGS = {"native": paper_n_rig, "roi": paper_n_rig, "reduced": paper_n_rig_reduced}
# paper N Table 7, pits of 25-34 cells, 2 m bins from 6-8 m to 18-20 m
PAPER_TABLE7 = (0.95, 0.93, 0.85, 0.75, 0.54, 0.31, 0.17)
SIZE_BINS = (1, 10_000)  # one size bin: every pit counts
GRID = GridSpec()


def cast_drive(rig: Rig, size_m: tuple[float, float], seed: int, roi: bool = False) -> dict:
    """Scans (float32 ranges per sensor), INS poses, true poses and the pit outline of one drive;
    with ``roi`` only the rays the envs' observation grid needs are cast (as ``rig="roi"``)."""
    length, width = size_m
    terrain = braking_track(
        ditch_distance_m=PIT_START_M,
        ditch_length_m=length,
        ditch_width_m=width,
        ditch_depth_m=PIT_DEPTH_M,
        seed=seed,
    )
    (pit,) = terrain.negative_obstacles
    rng = np.random.default_rng([seed, int(100 * length), int(100 * width)])
    drive: dict = {"ins": [], "truth": []} | {m.name: [] for m in rig.mounts}
    with World(terrain) as world:
        vehicle = Vehicle(world, rng=rng)
        caster = make_caster(world, "auto", exclude_body_ids=(vehicle.body_id,))
        selector = heights = None
        recent: list = []  # the drive's band sets (RoiSelector.subsets_for_bands)
        if roi:
            selector = RoiSelector(rig, RoiConfig(region_xy_m=ObservationConfig().grid.extent_xy_m))
            heights = HeightEnvelope(world, exclude_body_ids=(vehicle.body_id,))
        steps = round(FRAME_S / world.config.time_step_s)
        while True:
            vehicle.set_speed(SPEED_MPS)
            world.step(steps)
            true = vehicle.true_pose()
            near = world_outline_to_vehicle(pit.outline_xy_m, true)[:, 1].min()
            if near < NEAREST_M - 1.0:
                break
            subsets = selector.subsets_for_bands(heights.bands(true, selector.tiles), recent) if roi else None
            for name, s in scan_rig(rig, caster, true, rng=rng, subsets=subsets).items():
                drive[name].append(s.ranges_m.astype(np.float32))
            drive["ins"].append(vehicle.pose().as_array())
            drive["truth"].append(true.as_array())
    drive = {k: np.asarray(v) for k, v in drive.items()}
    drive["outline"] = np.asarray(pit.outline_xy_m)
    drive["rim_z"] = np.array(pit.floor_z_m + pit.depth_m)
    return drive


def load_or_cast(
    rig: Rig, size_m: tuple[float, float], seed: int, cache: Path | None, roi: bool = False
) -> dict:
    """One drive, from ``cache`` when there, else cast (and stored atomically when caching)."""
    if cache is None:
        return cast_drive(rig, size_m, seed, roi)
    models = "_".join(m.model.name for m in rig.mounts) + ("_roi" if roi else "")
    path = cache / f"{models}_{size_m[0]}x{size_m[1]}_seed{seed}.npz"
    if path.exists():
        with np.load(path) as data:
            return dict(data)
    drive = cast_drive(rig, size_m, seed, roi)
    cache.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=cache, suffix=".npz")
    with os.fdopen(fd, "wb") as f:
        np.savez_compressed(f, **drive)
    os.replace(tmp, path)
    return drive


def frame_scans(rig: Rig, drive: dict, k: int) -> dict[str, StructuredScan]:
    """Rebuild frame ``k``'s StructuredScans from the stored ranges."""
    pose = Pose.from_array(drive["truth"][k])
    return {
        m.name: StructuredScan(
            sensor=m.name,
            ranges_m=drive[m.name][k].astype(np.float64),
            azimuth_rad=m.model.azimuth_rad,
            elevation_rad=m.model.elevation_rad,
            rotation=m.rotation_matrix,
            translation_m=np.asarray(m.translation_m),
            pose=pose,
        )
        for m in rig.mounts
    }


def near_edge_lead_m(outlines: list[np.ndarray], truth: np.ndarray) -> float:
    """How far before the pit's near rim (along +y) the earliest detected outline overlapping the
    pit on the grid starts [m]; NaN when none overlaps it."""
    pit = convex_overlap_mask(truth[:, :2], GRID)
    leads = [
        float(truth[:, 1].min() - outline[:, 1].min())
        for outline in outlines
        if np.any(convex_overlap_mask(outline, GRID) & pit)
    ]
    return max(leads) if leads else float("nan")


class FarFrames:
    """The part of a frame the envs cast between frames with ``ObservationConfig.scan_far_from_m``:
    the rays that can return a point in the grid beyond ``from_m`` (a fixed height band of
    +-1.5 m, which holds the drives' pits and rough ground; the envs take theirs from the
    terrain), and that box as the detector's coverage."""

    def __init__(self, rig: Rig, from_m: float) -> None:
        self.coverage_xy_m = ObservationConfig(scan_every=2, scan_far_from_m=from_m).far_region_xy_m
        subsets = RoiSelector(rig, RoiConfig(region_xy_m=self.coverage_xy_m)).subsets(-1.5, 1.5)
        self.masks = {}
        for m in rig.mounts:
            mask = np.zeros(m.model.n_lasers * m.model.n_columns, dtype=bool)
            mask[subsets[m.name].index] = True
            self.masks[m.name] = mask.reshape(m.model.n_lasers, m.model.n_columns)

    def scans(self, rig: Rig, drive: dict, k: int) -> dict[str, StructuredScan]:
        """Frame ``k``'s scans with the rays outside the far part as no return."""
        whole = frame_scans(rig, drive, k)
        return {
            name: dataclasses.replace(s, ranges_m=np.where(self.masks[name], s.ranges_m, np.nan))
            for name, s in whole.items()
        }


def evaluate(
    rig: Rig,
    drives: list[dict],
    matching: DetectionEvalConfig,
    fusion: FusionConfig,
    scan_every: int = 1,
    far: FarFrames | None = None,
) -> tuple[dict[str, RecallTable], np.ndarray, np.ndarray]:
    """Recall tables per sensor mode over ``drives`` (each mode's detector reset per drive), and per
    fused frame the pit centre's distance and :func:`near_edge_lead_m`. The detectors get every
    ``scan_every``-th frame; the frames between are judged on the last detection carried to
    their INS pose, or with ``far`` on the detection of their far part."""
    detectors = {
        m: NegativeObstacleDetector(NegativeDetectorConfig(mode=m, fusion=fusion)) for m in SENSOR_MODES
    }
    tables = {m: RecallTable(matching) for m in SENSOR_MODES}
    distances, leads = [], []
    for drive in drives:
        for det in detectors.values():
            det.reset()
        last: dict[str, tuple[Pose, list[np.ndarray]]] = {}
        for k in range(len(drive["ins"])):
            ins = Pose.from_array(drive["ins"][k])
            truth = world_outline_to_vehicle(
                drive["outline"], Pose.from_array(drive["truth"][k]), drive["rim_z"]
            )
            coverage = None
            if k % scan_every == 0:
                scans = frame_scans(rig, drive, k)
            elif far is not None:
                scans, coverage = far.scans(rig, drive, k), far.coverage_xy_m
            else:
                scans = None
            for mode, det in detectors.items():
                if scans is not None:
                    detection = det.update(scans, ins, coverage)
                    last[mode] = (ins, [o.outline_xy_m for o in detection.obstacles])
                seen_at, seen = last[mode]
                outlines = [carry_points(o, seen_at, ins) for o in seen] if scans is None else seen
                tables[mode].add(match_frame(outlines, [truth], GRID, matching))
                if mode == "fused":
                    distances.append(float(np.hypot(*truth[:, :2].mean(axis=0))))
                    leads.append(near_edge_lead_m(outlines, truth))
    return tables, np.asarray(distances), np.asarray(leads)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8, help="terrain/noise seeds per pit size (>= 8)")
    parser.add_argument("--rig", choices=sorted(RIGS), default="native", help="sensor rig")
    parser.add_argument("--cache", type=Path, default=None, help="directory keeping the cast scans")
    parser.add_argument(
        "--bin-by",
        choices=("centre", "nearest"),
        default="centre",
        help="distance of a pit: its cells' centre (paper N §4.2, default) or its nearest cell",
    )
    parser.add_argument("--tighten", action="store_true", help="FusionConfig(tighten_on_match=True)")
    parser.add_argument(
        "--scan-every",
        default="1",
        help="comma-separated ObservationConfig.scan_every values; the first is the main table",
    )
    parser.add_argument(
        "--far-from",
        type=float,
        default=None,
        metavar="M",
        help="ObservationConfig.scan_far_from_m for the further --scan-every values: the frames "
        "between get the grid's part beyond M metres instead of a carried detection",
    )
    args = parser.parse_args()
    every = [int(k) for k in args.scan_every.split(",")]
    if not every or min(every) < 1:
        parser.error(f"--scan-every takes ints >= 1, got {args.scan_every!r}")
    matching = DetectionEvalConfig(size_bin_edges_cells=SIZE_BINS, bin_distance=args.bin_by)
    rig = RIGS[args.rig]()
    drives = [
        load_or_cast(rig, size, seed, args.cache, roi=args.rig == "roi")
        for seed in range(args.seeds)
        for size in PAPER_N_PIT_SIZES_M
    ]
    fusion = FusionConfig(tighten_on_match=args.tighten)
    tables, distances, leads = evaluate(rig, drives, matching, fusion, every[0])
    edges = matching.distance_bin_edges_m
    bins = [f"{lo:.0f}-{hi:.0f} m" for lo, hi in itertools.pairwise(edges)]
    recall = {m: t.recall()[0] for m, t in tables.items()}
    print(
        f"{len(drives)} drives ({args.seeds} seeds x {len(PAPER_N_PIT_SIZES_M)} pit sizes), rig {args.rig}, "
        f"distance bins by the pit's {args.bin_by}, tighten_on_match={args.tighten}, scan_every={every[0]}"
    )
    print(f"frames per bin: {' '.join(str(n) for n in tables['fused'].seen[0])}")
    print(f"{'mode':<14}" + "".join(f"{b:>9}" for b in bins))
    for mode, label in (("fused", "fused"), ("hdl64", "HDL-64 only"), ("hdl32", "HDL-32 only")):
        print(f"{label:<14}" + "".join(f"{r:9.2f}" for r in recall[mode]))
    print(f"{'paper Table 7':<14}" + "".join(f"{r:9.2f}" for r in PAPER_TABLE7))
    below = [b for b, r, p in zip(bins, recall["fused"], PAPER_TABLE7, strict=True) if not r >= p]
    print(f"fused below paper N Table 7 in: {', '.join(below) if below else 'no bin'}")
    print(f"false alarms per frame (fused): {tables['fused'].false_alarms_per_frame():.3f}")
    where = np.digitize(distances, edges) - 1  # bin of each frame by the pit centre's distance
    mean_lead = [
        np.nanmean(leads[where == k]) if np.any(~np.isnan(leads[where == k])) else np.nan
        for k in range(len(bins))
    ]
    print(
        f"{'near-edge lead':<14}" + "".join(f"{v:9.2f}" for v in mean_lead) + "   (fused, m before the rim)"
    )
    near = (distances >= 6.0) & (distances < 12.0) & ~np.isnan(leads)
    print(f"near_edge_lead_6_12_m={np.mean(leads[near]):.2f}")
    far = np.asarray(edges[:-1]) >= 12.0
    print(f"fused_recall_12_20={np.nanmean(recall['fused'][far]):.2f}")
    beyond = np.asarray(edges[:-1]) >= 14.0
    ok = bool(np.all(recall["hdl32"][beyond] >= recall["hdl64"][beyond]))
    print(f"fig16_order={'ok' if ok else 'violated'}")
    far = None if args.far_from is None else FarFrames(rig, args.far_from)
    for k in every[1:]:
        other, _, _ = evaluate(rig, drives, matching, fusion, k, far)
        between = "carried" if far is None else f"detected beyond {args.far_from:g} m"
        print(f"scan_every={k}: a detector frame every {k} steps, the frames between {between}")
        for mode, label in (("fused", "fused"), ("hdl64", "HDL-64 only"), ("hdl32", "HDL-32 only")):
            print(f"{label:<14}" + "".join(f"{r:9.2f}" for r in other[mode].recall()[0]))
        drop = recall["fused"] - other["fused"].recall()[0]
        print(f"false alarms per frame (fused): {other['fused'].false_alarms_per_frame():.3f}")
        print(f"scan_every_{k}_max_drop={np.nanmax(drop):.2f} (fused, against scan_every={every[0]})")


if __name__ == "__main__":
    main()
