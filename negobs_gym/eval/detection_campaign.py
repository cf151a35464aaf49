"""Detection campaign (paper N §4.2): recall by size and distance, false alarms, the Fig. 16 comparison.

Each episode (one seed) drives a straight rough course holding paper N's obstacle mix (pits of
100x50, 100x80, 150x60 and 100x100 cm, each side scaled by a factor in ``size_scale``, depths 0.3-1.5 m,
beside the wheel tracks, rocks and mounds on the verges as clutter) at a seeded speed between
``min_speed_mps`` and 25 km/h. Every 10 Hz frame the rig is cast once (sensor noise on) and
paper N's detector runs in each sensor mode of ``modes`` on the same scans (fused, HDL-64 only,
HDL-32 only: paper N Fig. 16) with the INS pose. Every ground-truth obstacle with a cell on the
grid gives one CSV row: its size in 20 cm cells, the distance of its centre from the vehicle
(INS) origin, and whether each mode recalled it (matching of :mod:`negobs_gym.eval.detection`).
Every frame gives one row of false alarms per mode, on and off the track.

The summary (:class:`DetectionSummary`) is computed from the CSVs alone, so a resumed or
distributed campaign summarises exactly like a serial one.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.core.geometry import distance_to_polyline
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.campaign import Episode, Rows, RunOptions, format_row, read_csv
from negobs_gym.eval.detection import (
    DetectionEvalConfig,
    match_frame,
    track_border_mask,
    world_outline_to_vehicle,
)
from negobs_gym.eval.detection_causes import CauseConfig
from negobs_gym.eval.stats import interval_list, nan_to_none, seed_bootstrap_interval
from negobs_gym.eval.tables import bin_labels

BRAKING_SPEED_MPS = 25.0 / 3.6  # paper N §4: the ALV drives at most 25 km/h off-road
FRAME_S = 0.1  # paper N: HDL-64 / HDL-32 at 10 Hz
SETTLE_S = 0.5  # suspension settling before the first frame (engineering choice)
SENSOR_MODES = ("fused", "hdl64", "hdl32")  # paper N Fig. 16: fused, 64 only, 32 only
FIG16_CELLS = (25, 35)  # paper N Fig. 16 counts 25-34-cell obstacles only, 6-20 m

OBSTACLE_COLUMNS = (
    "episode",
    "seed",
    "frame",
    "obstacle",
    "cells",
    "centre_distance_m",
    *(f"recalled_{m}" for m in SENSOR_MODES),
)
FRAME_COLUMNS = (
    "episode",
    "seed",
    "frame",
    "speed_mps",
    "travelled_m",
    "lateral_m",
    *(f"{k}_{m}" for m in SENSOR_MODES for k in ("detections", "false_alarms_on", "false_alarms_off")),
)
# one row per false alarm: its sensor mode, the true terrain class under it
# (:mod:`negobs_gym.eval.detection_causes`) and where it lies in the vehicle frame
FALSE_ALARM_COLUMNS = ("episode", "seed", "frame", "mode", "cause", "on_track", "x_m", "y_m", "distance_m")


@dataclass(frozen=True, kw_only=True)
class DetectionCampaignConfig:
    """What one detection campaign drives and how it is judged."""

    seeds: int = 10
    frames: int = 1000  # total frames of the campaign, split evenly over the seeds
    rig: str = "native"  # paper N's rig at native resolution ("reduced": half, for quick runs)
    sensor_noise: bool = True
    max_speed_mps: float = BRAKING_SPEED_MPS  # paper N §4: 25 km/h
    # "and slower": paper N gives no speed profile; 10 km/h is a slow off-road pace
    min_speed_mps: float = 10.0 / 3.6
    # obstacle spacing along the course; paper N's frames hold 1.4 obstacles on average (5350
    # marked in 3866 frames, §4.1), i.e. one every ~10 m within the 6-20 m band
    spacing_m: tuple[float, float] = (7.0, 11.0)
    # lateral offset of a pit's centre: beside the wheel tracks so the drive never falls in (a
    # 1.9 m wide vehicle, pits up to ~0.9 m half-size); paper N's pits lie on and beside the road
    lateral_m: tuple[float, float] = (2.4, 3.2)
    # "a spread around" paper N's four sizes: each side scaled by a factor in this range. Paper N
    # counts cells of hand-marked areas, larger than the pit by ~30 x 20 cm (§4.2: a 100x60 cm pit
    # is 24 real, 35 marked cells); we count the real rim's cells, so the sides grow by up to 50 %
    # for the rim counts to span Table 7's 15-55 cells
    size_scale: tuple[float, float] = (1.0, 1.5)
    depth_m: tuple[float, float] = (0.3, 1.5)  # paper N §4: 0.3-1.5 m deep
    clutter_per_100m: float = 10.0  # rocks and mounds on the verges (not in paper N)
    raycast_backend: str = "auto"
    matching: DetectionEvalConfig = field(default_factory=DetectionEvalConfig)  # grid matching, bins
    causes: CauseConfig = field(default_factory=CauseConfig)  # terrain classes of the false alarms
    # the detector judged: "default" (NegativeDetectorConfig()) or "paper" (paper N as published,
    # NegativeDetectorConfig.paper()), then each "PATH=VALUE" of detector_set (e.g. "hdl64.gamma1=2")
    detector: str = "default"
    detector_set: tuple[str, ...] = ()
    # PNGs of the frames with the most fused false alarms, redriven after the campaign (0: none)
    worst_frames: int = 3

    def __post_init__(self) -> None:
        require(self.seeds >= 1, "seeds", f"must be >= 1, got {self.seeds}")
        require(self.frames >= self.seeds, "frames", f"must be >= seeds ({self.seeds}), got {self.frames}")
        require(self.rig in ("native", "reduced"), "rig", f"must be 'native' or 'reduced', got {self.rig!r}")
        require(
            0 < self.min_speed_mps <= self.max_speed_mps,
            "min_speed_mps",
            f"must be in (0, max_speed_mps], got {self.min_speed_mps}",
        )
        for name in ("spacing_m", "lateral_m", "size_scale", "depth_m"):
            lo, hi = getattr(self, name)
            require(0 < lo <= hi and math.isfinite(hi), name, "must be (low, high), 0 < low <= high")
        require(self.clutter_per_100m >= 0, "clutter_per_100m", "must be >= 0")
        if not isinstance(self.matching, DetectionEvalConfig):
            raise ConfigError("matching", "must be a DetectionEvalConfig")
        if not isinstance(self.causes, CauseConfig):
            raise ConfigError("causes", "must be a CauseConfig")
        require(
            isinstance(self.worst_frames, int) and self.worst_frames >= 0,
            "worst_frames",
            f"must be an integer >= 0, got {self.worst_frames!r}",
        )
        self.campaign_detector()  # a bad preset name or assignment fails here, not in a worker

    def campaign_detector(self) -> Any:
        """The :class:`~negobs_gym.detector.NegativeDetectorConfig` this campaign judges."""
        from negobs_gym.detector.negative import detector_preset, with_settings

        return with_settings(detector_preset(self.detector), self.detector_set)

    def frames_of(self, index: int) -> int:
        """Frames of the ``index``-th seed (the remainder goes to the first seeds)."""
        base, extra = divmod(self.frames, self.seeds)
        return base + (1 if index < extra else 0)


def episodes(config: DetectionCampaignConfig) -> list[Episode]:
    """One episode per seed 0..seeds-1."""
    return [
        Episode(f"seed{seed:05d}", {"config": config, "seed": seed, "frames": config.frames_of(seed)})
        for seed in range(config.seeds)
    ]


def detection_course(
    config: DetectionCampaignConfig, seed: int, length_m: float, extra_positives: Any = None
) -> Any:
    """Straight rough track with paper N's pit mix beside the wheel tracks and verge clutter.

    ``extra_positives``, when given, is called with the course's pits (``NegativeObstacleSpec``)
    and returns more positive obstacles to place (the PEM's courses add some on the track).
    """
    from negobs_gym.sim.terrain import TerrainConfig, generate_terrain

    negatives, positives = detection_course_obstacles(config, seed, length_m)
    if extra_positives is not None:
        positives += tuple(extra_positives(tuple(negatives)))
    terrain_config = TerrainConfig(
        length_m=length_m, negative_obstacles=tuple(negatives), positive_obstacles=positives
    )
    return generate_terrain(terrain_config, seed)


def detection_course_obstacles(
    config: DetectionCampaignConfig, seed: int, length_m: float
) -> tuple[list, tuple]:
    """The pits and the verge clutter of :func:`detection_course` (obstacle specs)."""
    from negobs_gym.sim.carving import PAPER_N_PIT_SIZES_M, NegativeObstacleSpec, PositiveObstacleSpec

    layout = np.random.default_rng([seed, 2])
    negatives: list[NegativeObstacleSpec] = []
    station, side = 8.0 + float(layout.uniform(*config.spacing_m)), float(layout.choice([-1.0, 1.0]))
    while station < length_m - 5.0:
        length, width = PAPER_N_PIT_SIZES_M[int(layout.integers(len(PAPER_N_PIT_SIZES_M)))]
        scale = layout.uniform(*config.size_scale, size=2)
        negatives.append(
            NegativeObstacleSpec(
                kind="pit",
                length_m=float(length * scale[0]),
                width_m=float(width * scale[1]),
                depth_m=float(layout.uniform(*config.depth_m)),
                station_m=station,
                lateral_m=side * float(layout.uniform(*config.lateral_m)),
                yaw_deg=float(layout.choice([0.0, 90.0])),
            )
        )
        station += float(layout.uniform(*config.spacing_m))
        side = -side if layout.uniform() < 0.7 else side
    n_clutter = round(config.clutter_per_100m * length_m / 100.0)
    positives = tuple(
        PositiveObstacleSpec(
            kind=str(layout.choice(["rock", "mound"])),
            station_m=float(layout.uniform(5.0, length_m - 2.0)),
            lateral_m=float(layout.choice([-1.0, 1.0]) * layout.uniform(3.6, 4.6)),
        )
        for _ in range(n_clutter)
    )
    return negatives, positives


def _lateral_offset(pose: Any, centreline: np.ndarray) -> float:
    """Vehicle x minus the centre line's x at its y (the course runs along +Y)."""
    return pose.x - float(np.interp(pose.y, centreline[:, 1], centreline[:, 0]))


@dataclass(frozen=True)
class JudgedFrame:
    """One frame judged in every sensor mode (paper N §4.2 matching).

    ``recalled[mode]``: which truths each mode recalled; ``counts``: per mode, detections and false
    alarms on and off the track (:data:`FRAME_COLUMNS` order); ``false_alarms[mode]``: each false
    alarm's vehicle-frame outline and whether its centre lies on the track.
    """

    recalled: dict[str, np.ndarray]
    counts: list[int]
    truth_cells: np.ndarray
    truth_centre_m: np.ndarray
    false_alarms: dict[str, list[tuple[np.ndarray, bool]]]


def _judge_frame(
    detections: dict[str, Any],
    truths: list[np.ndarray],
    centre_line: np.ndarray,
    track_width_m: float,
    grid: Any,
    matching: DetectionEvalConfig,
    modes: tuple[str, ...] = SENSOR_MODES,
) -> JudgedFrame:
    """Judge one frame's detections of each of ``modes`` against the truths."""
    border = track_border_mask(centre_line, track_width_m, grid, matching.border_band_m)
    recalled, counts, false_alarms = {}, [], {}
    for m in modes:
        outlines = [np.asarray(o.outline_xy_m) for o in detections[m].obstacles]
        match = match_frame(outlines, truths, grid, matching, border)
        centres = np.array([o.mean(axis=0) for o in outlines]).reshape(-1, 2)
        on_track = distance_to_polyline(centres, centre_line) <= 0.5 * track_width_m
        on = int(np.count_nonzero(on_track[match.false_alarm_index]))
        recalled[m] = match.truth_recalled
        counts += [match.detections, on, match.false_alarms - on]
        false_alarms[m] = [(outlines[k], bool(on_track[k])) for k in match.false_alarm_index]
    return JudgedFrame(recalled, counts, match.truth_cells, match.truth_centre_distance_m, false_alarms)


@dataclass(frozen=True, eq=False)
class DrivenFrame:
    """One frame of a detection course: what the rig saw, what each mode detected, and the truth."""

    frame: int
    speed_mps: float
    travelled_m: float
    lateral_m: float
    pose: Any  # true pose (the truth is mapped with it)
    ins_poses: dict[str, Any]  # per sensor mode, the INS pose its detector was given
    scans: dict[str, Any]
    detections: dict[str, Any]  # per sensor mode
    truths: list[np.ndarray]  # vehicle-frame rim outlines, one per negative obstacle
    centre_line: np.ndarray  # vehicle frame
    judged: JudgedFrame


def drive_course(
    config: DetectionCampaignConfig,
    seed: int,
    n_frames: int,
    detector_config: Any = None,
    modes: tuple[str, ...] = SENSOR_MODES,
) -> Iterator[tuple[Any, DrivenFrame]]:
    """Drive course ``seed`` for ``n_frames`` frames: yields ``(terrain, frame)`` per frame.

    ``detector_config`` (a :class:`~negobs_gym.detector.NegativeDetectorConfig`, its ``mode`` and
    ``grid`` replaced per mode) is the detector judged; None = :meth:`campaign_detector`. ``modes``
    (a subset of :data:`SENSOR_MODES`, in that order) are run and judged; the scans are the same.
    The course's length follows ``n_frames``: to see a campaign's frame, drive its episode's frames.
    """
    require(
        len(modes) > 0 and all(m in SENSOR_MODES for m in modes),
        "modes",
        f"must be a non-empty subset of {SENSOR_MODES}, got {modes!r}",
    )
    from negobs_gym.core.grid import GridSpec
    from negobs_gym.detector import NegativeObstacleDetector
    from negobs_gym.sensors.lidar import scan_rig
    from negobs_gym.sensors.noise import NoiseConfig
    from negobs_gym.sensors.raycast import make_caster
    from negobs_gym.sensors.rigs import paper_n_rig, paper_n_rig_reduced
    from negobs_gym.sim.vehicle import Vehicle
    from negobs_gym.sim.world import World

    cfg = config
    speed = float(np.random.default_rng([seed, 1]).uniform(cfg.min_speed_mps, cfg.max_speed_mps))
    terrain = detection_course(cfg, seed, length_m=speed * FRAME_S * n_frames + 35.0)
    grid = GridSpec()  # paper N §3.4: the 20 cm vehicle grid (detector and matching alike)
    base = detector_config if detector_config is not None else cfg.campaign_detector()
    detectors = {m: NegativeObstacleDetector(dataclasses.replace(base, mode=m, grid=grid)) for m in modes}
    rng = np.random.default_rng([seed, 3])
    rig = paper_n_rig() if cfg.rig == "native" else paper_n_rig_reduced()
    noise = NoiseConfig(enabled=cfg.sensor_noise)
    centreline = np.asarray(terrain.track.centreline_xy_m, dtype=np.float64)
    # 1 m segments are exact on a straight course and within 7 mm on an 18 m bend
    step = max(1, round(1.0 / max(float(np.median(np.diff(terrain.track.stations_m))), 1e-3)))
    centreline = np.vstack([centreline[::step], centreline[-1:]])
    with World(terrain) as world:
        vehicle = Vehicle(world, rng=rng)
        caster = make_caster(world, cfg.raycast_backend, exclude_body_ids=(vehicle.body_id,))
        steps = round(FRAME_S / world.config.time_step_s)
        world.step(round(SETTLE_S / world.config.time_step_s))
        last = vehicle.true_pose()
        for frame in range(n_frames):
            # hold the centre line: steer against the lateral offset and the heading error
            steer = 0.5 * _lateral_offset(last, centreline) - 2.0 * last.yaw
            vehicle.apply(0.0, 0.0, float(np.clip(steer, -1.0, 1.0)))
            vehicle.set_speed(speed)
            world.step(steps)
            pose = vehicle.true_pose()
            scans = scan_rig(rig, caster, pose, noise=noise, rng=rng, timestamp_s=world.sim_time_s)
            ins_poses = {m: vehicle.pose() for m in detectors}  # one INS draw per mode, in mode order
            detections = {m: d.update(scans, ins_poses[m]) for m, d in detectors.items()}
            travelled = math.hypot(pose.x - last.x, pose.y - last.y)
            last = pose
            truths = [
                world_outline_to_vehicle(ob.outline_xy_m, pose, ob.floor_z_m + ob.depth_m)
                for ob in terrain.negative_obstacles
            ]
            centre_line = world_outline_to_vehicle(centreline, pose)
            judged = _judge_frame(
                detections, truths, centre_line, terrain.track.width_m, grid, cfg.matching, modes
            )
            lateral = _lateral_offset(pose, centreline)
            yield (
                terrain,
                DrivenFrame(
                    frame,
                    speed,
                    travelled,
                    lateral,
                    pose,
                    ins_poses,
                    scans,
                    detections,
                    truths,
                    centre_line,
                    judged,
                ),
            )


def run_episode(episode: Episode) -> Rows:
    """Drive one seeded course; its rows of :data:`OBSTACLE_COLUMNS`, ``FRAME_COLUMNS`` and
    ``FALSE_ALARM_COLUMNS``."""
    from negobs_gym.eval.detection_causes import TerrainClassifier

    cfg: DetectionCampaignConfig = episode.args["config"]
    seed, n_frames = int(episode.args["seed"]), int(episode.args["frames"])
    obstacles, frames, false_alarms = [], [], []
    classifier = None
    for terrain, f in drive_course(cfg, seed, n_frames):
        if classifier is None:
            classifier = TerrainClassifier(terrain, cfg.causes)
        judged = f.judged
        row = [episode.key, seed, f.frame, f.speed_mps, f.travelled_m, f.lateral_m]
        frames.append(format_row([*row, *judged.counts]))
        for k, ob in enumerate(terrain.negative_obstacles):
            if int(judged.truth_cells[k]) == 0:
                continue
            hits = [bool(judged.recalled[m][k]) for m in SENSOR_MODES]
            row = [episode.key, seed, f.frame, ob.obstacle_id, int(judged.truth_cells[k])]
            obstacles.append(format_row([*row, float(judged.truth_centre_m[k]), *hits]))
        for m in SENSOR_MODES:
            for outline, on_track in judged.false_alarms[m]:
                world_xy = f.pose.to_world(np.column_stack([outline, np.zeros(len(outline))]))[:, :2]
                centre = outline.mean(axis=0)
                cause = classifier.classify(world_xy)
                row = [episode.key, seed, f.frame, m, cause, on_track, float(centre[0]), float(centre[1])]
                false_alarms.append(format_row([*row, float(np.hypot(*centre))]))
    return {"obstacles": obstacles, "frames": frames, "false_alarms": false_alarms}


# -- summary -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class DetectionSummary:
    """Campaign totals in paper N's layouts; round-trips through :meth:`to_json` / :meth:`from_json`.

    ``occurrences[s][d]`` is Table 6 (ground-truth obstacle-frames per size and distance bin),
    ``recalled[mode][s][d]`` the recalled ones (Table 7 = recalled / occurrences). False alarms
    per mode: ``total``, ``on_track``, ``off_track`` counts. ``fig16[mode][d]`` is the recall of
    25-34-cell obstacles per distance bin (None where none was seen), ``fig16_interval[mode][d]``
    its 95 % interval, ``[low, high]``, from resampling the courses (seeds) with replacement
    (:func:`~negobs_gym.eval.stats.seed_bootstrap_interval`; None where fewer than two courses saw
    such an obstacle; empty in summaries written before it).
    """

    episodes: int
    frames: int
    km: float
    size_bins: list[str]
    distance_bins: list[str]
    occurrences: list[list[int]]
    recalled: dict[str, list[list[int]]]
    false_alarms: dict[str, dict[str, int]]
    fig16: dict[str, list[float | None]]
    fig16_interval: dict[str, list[list[float] | None]] = field(default_factory=dict)
    # false alarms per mode and terrain class (:data:`~negobs_gym.eval.detection_causes.CAUSES`);
    # empty in summaries written before the classes were recorded
    false_alarm_causes: dict[str, dict[str, int]] = field(default_factory=dict)

    def recall(self, mode: str = "fused") -> np.ndarray:
        """Table 7 recall of ``mode`` (NaN where nothing was seen)."""
        seen = np.asarray(self.occurrences, dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(seen > 0, np.asarray(self.recalled[mode]) / np.maximum(seen, 1), np.nan)

    def false_alarm_rates(self, mode: str = "fused") -> dict[str, float]:
        """False alarms per frame and per km (total, on and off the track)."""
        counts = self.false_alarms[mode]
        per = {"per_frame": counts["total"] / self.frames if self.frames else math.nan}
        for k in ("total", "on_track", "off_track"):
            per[f"{k}_per_km"] = counts[k] / self.km if self.km > 0 else math.nan
        return per

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=1, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> DetectionSummary:
        return cls(**json.loads(text))


def summarize(
    obstacles_csv: str | Path,
    frames_csv: str | Path,
    config: DetectionEvalConfig,
    false_alarms_csv: str | Path | None = None,
) -> DetectionSummary:
    """Table 6/7 counts, false alarms, their causes (given ``false_alarms_csv``) and Fig. 16 curves
    from the campaign's CSVs."""
    from negobs_gym.eval.detection_causes import CAUSES

    causes: dict[str, dict[str, int]] = {}
    if false_alarms_csv is not None:
        causes = {m: dict.fromkeys(CAUSES, 0) for m in SENSOR_MODES}
        for r in read_csv(false_alarms_csv):
            causes[r["mode"]][r["cause"]] += 1
    obs_rows = read_csv(obstacles_csv)
    frame_rows = read_csv(frames_csv)
    size_edges, dist_edges = config.size_bin_edges_cells, config.distance_bin_edges_m
    shape = (len(size_edges) - 1, len(dist_edges) - 1)
    rows = _ObstacleRows.parse(obs_rows, config)
    s = np.digitize(rows.cells, size_edges) - 1
    d = rows.distance_bin
    ok = (s >= 0) & (s < shape[0]) & (d >= 0) & (d < shape[1])
    occurrences = np.zeros(shape, dtype=np.int64)
    np.add.at(occurrences, (s[ok], d[ok]), 1)
    recalled, fig16, fig16_interval, false_alarms = {}, {}, {}, {}
    by_course = rows.fig16_by_course(shape[1])
    for m in SENSOR_MODES:
        table = np.zeros(shape, dtype=np.int64)
        np.add.at(table, (s[ok], d[ok]), rows.recalled[m][ok].astype(np.int64))
        recalled[m] = table.tolist()
        fig16[m] = nan_to_none(by_course.recall(m))
        fig16_interval[m] = by_course.intervals(m)
        on = sum(int(r[f"false_alarms_on_{m}"]) for r in frame_rows)
        off = sum(int(r[f"false_alarms_off_{m}"]) for r in frame_rows)
        false_alarms[m] = {"total": on + off, "on_track": on, "off_track": off}
    return DetectionSummary(
        episodes=len({r["episode"] for r in frame_rows}),
        frames=len(frame_rows),
        km=sum(float(r["travelled_m"]) for r in frame_rows) / 1000.0,
        size_bins=bin_labels(size_edges),
        distance_bins=bin_labels(dist_edges, " m"),
        occurrences=occurrences.tolist(),
        recalled=recalled,
        false_alarms=false_alarms,
        fig16=fig16,
        fig16_interval=fig16_interval,
        false_alarm_causes=causes,
    )


def cause_rows(summary: DetectionSummary) -> list[list[Any]]:
    """The cause table: per terrain class (in :data:`CAUSES` order), each mode's false alarms per km
    (and count)."""
    from negobs_gym.eval.detection_causes import CAUSES

    rows = []
    known = next(iter(summary.false_alarm_causes.values()), {})
    for cause in [c for c in CAUSES if c in known] + sorted(set(known) - set(CAUSES)):
        row: list[Any] = [cause]
        for m in SENSOR_MODES:
            n = summary.false_alarm_causes[m][cause]
            row += [n, n / summary.km if summary.km > 0 else math.nan]
        rows.append(row)
    return rows


CAUSE_HEADER = ("cause", *(f"{m} {k}" for m in SENSOR_MODES for k in ("count", "per km")))


@dataclass(frozen=True)
class CourseCounts:
    """Fig. 16's obstacle-frames (25-34 cells, per distance bin) counted per course: the unit a
    campaign's uncertainty is resampled in (a course's frames see the same pits)."""

    seeds: np.ndarray  # (courses,), ascending
    seen: np.ndarray  # (courses, distance bins)
    recalled: dict[str, np.ndarray]  # per sensor mode, like seen

    def recall(self, mode: str) -> np.ndarray:
        """Per distance bin, the recall pooled over the courses (NaN where none was seen)."""
        seen = self.seen.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(seen > 0, self.recalled[mode].sum(axis=0) / np.maximum(seen, 1), np.nan)

    def intervals(self, mode: str) -> list[list[float] | None]:
        """Per distance bin, the 95 % interval of the pooled recall over the courses resampled
        (None: seen by fewer than two courses)."""
        if self.seeds.size < 2:
            return [None] * self.seen.shape[1]
        return interval_list(*seed_bootstrap_interval(self.recalled[mode], self.seen))

    def on(self, seeds: np.ndarray) -> CourseCounts:
        """The counts of ``seeds`` in their order, zeros for a course with no row here (no pit of
        Fig. 16's sizes in view)."""
        seeds = np.asarray(seeds, dtype=np.int64)
        at = np.searchsorted(self.seeds, seeds)
        here = at < self.seeds.size
        here[here] = self.seeds[at[here]] == seeds[here]

        def take(counts: np.ndarray) -> np.ndarray:
            out = np.zeros((seeds.size, counts.shape[1]))
            out[here] = counts[at[here]]
            return out

        return CourseCounts(seeds, take(self.seen), {m: take(c) for m, c in self.recalled.items()})


def fig16_counts_by_course(obstacles_csv: str | Path, config: DetectionEvalConfig) -> CourseCounts:
    """The per-course Fig. 16 counts of a campaign's ``obstacles.csv``."""
    return _ObstacleRows.parse(read_csv(obstacles_csv), config).fig16_by_course(
        len(config.distance_bin_edges_m) - 1
    )


@dataclass(frozen=True)
class _ObstacleRows:
    """``obstacles.csv`` as columns: each row's course, rim cells, distance bin and recall flags."""

    seeds: np.ndarray
    cells: np.ndarray
    distance_bin: np.ndarray  # -1 or beyond the last: outside the bins
    recalled: dict[str, np.ndarray]  # per sensor mode, bool

    @classmethod
    def parse(cls, rows: list[dict[str, str]], config: DetectionEvalConfig) -> _ObstacleRows:
        dist = np.array([float(r["centre_distance_m"]) for r in rows], dtype=np.float64)
        return cls(
            seeds=np.array([int(r["seed"]) for r in rows], dtype=np.int64),
            cells=np.array([int(r["cells"]) for r in rows], dtype=np.int64),
            distance_bin=np.digitize(dist, config.distance_bin_edges_m) - 1,
            recalled={
                m: np.array([r[f"recalled_{m}"] == "1" for r in rows], dtype=bool) for m in SENSOR_MODES
            },
        )

    def fig16_by_course(self, bins: int) -> CourseCounts:
        d = self.distance_bin
        fig = (self.cells >= FIG16_CELLS[0]) & (self.cells < FIG16_CELLS[1]) & (d >= 0) & (d < bins)
        seeds, course = np.unique(self.seeds, return_inverse=True)
        index = (course[fig], d[fig])
        seen = np.zeros((seeds.size, bins))
        np.add.at(seen, index, 1.0)
        recalled = {}
        for m, hit in self.recalled.items():
            recalled[m] = np.zeros((seeds.size, bins))
            np.add.at(recalled[m], index, hit[fig].astype(float))
        return CourseCounts(seeds, seen, recalled)


def _fig16_cell(summary: DetectionSummary, mode: str, j: int) -> str:
    """A Fig. 16 table cell: the recall and, where known, its 95 % interval over the courses."""
    value = summary.fig16[mode][j]
    if value is None:
        return "-"
    interval = summary.fig16_interval.get(mode, [None] * len(summary.fig16[mode]))[j]
    return f"{value:.3f}" if interval is None else f"{value:.3f} ({interval[0]:.2f}-{interval[1]:.2f})"


def report_markdown(summary: DetectionSummary) -> str:
    """Tables 6 and 7 (ours beside paper N's), false alarms and the Fig. 16 curves as markdown."""
    from negobs_gym.eval.tables import key_value_table, occurrence_table, paper_n_fig16_fused, recall_table

    parts = [
        f"# Detection campaign: {summary.episodes} courses, {summary.frames} frames, {summary.km:.3f} km",
        "## Occurrences, ours (paper N Table 6)",
        occurrence_table(summary.occurrences, summary.size_bins, summary.distance_bins),
    ]
    for m in SENSOR_MODES:
        parts += [
            f"## Recall, {m}: ours (paper N Table 7, fused)",
            recall_table(summary.recall(m), summary.size_bins, summary.distance_bins),
        ]
    fa_rows = []
    for m in SENSOR_MODES:
        rates = summary.false_alarm_rates(m)
        counts = summary.false_alarms[m]
        fa_rows.append(
            [
                m,
                counts["total"],
                rates["per_frame"],
                rates["total_per_km"],
                rates["on_track_per_km"],
                rates["off_track_per_km"],
            ]
        )
    parts += [
        "## False alarms",
        key_value_table(
            ["mode", "count", "per frame", "per km", "on track per km", "off track per km"], fa_rows
        ),
        *(
            [
                "## False alarms by the terrain under them",
                key_value_table(list(CAUSE_HEADER), cause_rows(summary)),
            ]
            if summary.false_alarm_causes
            else []
        ),
        "## Fig. 16: recall of 25-34-cell obstacles (95 % interval over the courses)",
        key_value_table(
            ["distance", "paper N fused", *SENSOR_MODES],
            [
                [d, paper, *(_fig16_cell(summary, m, j) for m in SENSOR_MODES)]
                for j, (d, paper) in enumerate(zip(summary.distance_bins, paper_n_fig16_fused(), strict=True))
            ],
        ),
    ]
    return "\n\n".join(parts) + "\n"


@dataclass(frozen=True)
class DetectionOutputs:
    """Files of a finished detection campaign."""

    obstacles_csv: Path
    frames_csv: Path
    summary_json: Path
    tables_md: Path
    fig16_png: Path
    heatmap_png: Path
    summary: DetectionSummary
    false_alarms_csv: Path | None = None
    causes_csv: Path | None = None
    causes_png: Path | None = None
    worst_frame_pngs: tuple[Path, ...] = ()


def worst_frames(false_alarms_csv: str | Path, count: int, mode: str = "fused") -> list[tuple[int, int, int]]:
    """The ``count`` frames with the most false alarms of ``mode``, as ``(seed, frame, false alarms)``,
    most first (ties: lower seed, then earlier frame)."""
    tally: dict[tuple[int, int], int] = {}
    for r in read_csv(false_alarms_csv):
        if r["mode"] == mode:
            key = (int(r["seed"]), int(r["frame"]))
            tally[key] = tally.get(key, 0) + 1
    ranked = sorted(tally.items(), key=lambda kv: (-kv[1], kv[0]))
    return [(seed, frame, n) for (seed, frame), n in ranked[:count]]


def write_worst_frames(
    config: DetectionCampaignConfig, false_alarms_csv: Path, out: Path
) -> tuple[Path, ...]:
    """Redrive the courses of the frames with the most fused false alarms (the drive is
    deterministic) and draw each (:func:`~negobs_gym.eval.detection_causes.frame_plot`)."""
    from negobs_gym.eval.detection_causes import frame_plot

    paths = []
    for seed, frame, n in worst_frames(false_alarms_csv, config.worst_frames):
        # the course's length follows its frame count: drive the episode's frames, stop at this one
        for terrain, f in drive_course(config, seed, config.frames_of(seed)):
            if f.frame == frame:
                title = f"course {seed}, frame {frame}: {n} fused false alarms"
                path = out / f"fa_seed{seed:05d}_frame{frame:04d}.png"
                paths.append(frame_plot(terrain, f, SENSOR_MODES, path, title))
                break
    return tuple(paths)


def run_detection_campaign(
    config: DetectionCampaignConfig,
    out_dir: str | Path,
    options: RunOptions | None = None,
) -> DetectionOutputs:
    """Run (or resume) the campaign and write its CSVs, summary JSON, tables and figures to ``out_dir``."""
    from negobs_gym.core.files import write_text_atomic
    from negobs_gym.eval.campaign import run_campaign
    from negobs_gym.eval.detection_causes import cause_bar_plot
    from negobs_gym.eval.plots import fig16_plot, recall_heatmap
    from negobs_gym.eval.tables import PAPER_N_TABLE7, paper_n_fig16_fused

    out = Path(out_dir)
    tables = {"obstacles": OBSTACLE_COLUMNS, "frames": FRAME_COLUMNS, "false_alarms": FALSE_ALARM_COLUMNS}
    csvs = run_campaign(run_episode, episodes(config), out, tables, options, "detection courses")
    obstacles_csv, frames_csv, fa_csv = csvs["obstacles"], csvs["frames"], csvs["false_alarms"]
    summary = summarize(obstacles_csv, frames_csv, config.matching, fa_csv)
    causes_text = "\n".join(
        [",".join(CAUSE_HEADER).replace(" ", "_"), *(format_row(r) for r in cause_rows(summary))]
    )
    return DetectionOutputs(
        obstacles_csv=obstacles_csv,
        frames_csv=frames_csv,
        summary_json=write_text_atomic(out / "summary.json", summary.to_json()),
        tables_md=write_text_atomic(out / "tables.md", report_markdown(summary)),
        fig16_png=fig16_plot(summary.fig16, paper_n_fig16_fused(), summary.distance_bins, out / "fig16.png"),
        heatmap_png=recall_heatmap(
            summary.recall("fused"),
            np.asarray(PAPER_N_TABLE7),
            np.asarray(summary.occurrences),
            summary.size_bins,
            summary.distance_bins,
            out / "recall_heatmap.png",
        ),
        summary=summary,
        false_alarms_csv=fa_csv,
        causes_csv=write_text_atomic(out / "causes.csv", causes_text + "\n"),
        causes_png=cause_bar_plot(summary.false_alarm_causes, summary.km, out / "causes.png"),
        worst_frame_pngs=write_worst_frames(config, fa_csv, out),
    )
