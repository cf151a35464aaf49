"""The drives a PEM is fitted and checked on: detection courses through the env's detector grid.

Each seed drives one course of the detection campaign (:func:`~negobs_gym.eval.detection_campaign.
detection_course`: paper N's pit mix beside the wheel tracks, verge clutter, 10-25 km/h, a
P-controller on the centre line) with rocks and boxes added on the track beside the car's path
(:attr:`PemCampaignConfig.track_obstacles_per_100m`). Every 10 Hz frame the env's
:class:`~negobs_gym.envs.perception.DetectorGrid` (the observation settings the PEM is for)
observes; when a PEM is given, a second episode per seed drives the same course again (the same
true poses: the vehicle's generator is its own) with a :class:`~negobs_gym.envs.pem.PemGrid` per
channel instead, so a check of a new model after ``--resume`` keeps the detector's drives and
reruns only the PEM's (keyed by the model's and the PEM code's digest). Each grid's ``negative``
layer is judged against the true pits rasterised on the same grid, its ``positive`` layer (paper
T's LUX obstacles) against the positive obstacles' footprints, into one set of tables per channel
(the ``positive`` ones prefixed ``positive_``):

- ``sightings``: per frame, grid and obstacle on the grid, whether it is drawn (a connected blob
  of the layer owns one of its cells: :func:`blob_counts`, the ``positive`` footprints grown by
  :attr:`PemCampaignConfig.positive_match_cells` since the LUX draws a face on the footprint's
  edge; a rock's blob on a mound is the rock's alone),
  the drawn blobs' cells and their near- and far-edge offsets (range from the vehicle origin,
  drawn minus true);
- ``spurious``: per blob touching no obstacle, its terrain class (:class:`~negobs_gym.envs.pem.
  ClassRaster`, as the PEM looks it up), distance, cells, its distance from the nearest positive
  obstacle's footprint (``clutter_m``, empty beyond :data:`CLUTTER_REACH_M`) and from the nearest
  pit's rim (``pit_m``, empty beyond :data:`PIT_REACH_M`: the fit leaves a pit's fragments out of
  the false alarms, :attr:`PemCampaignConfig.pit_fragment_m`), whether a spurious
  blob of the frame before lay within :data:`SAME_ALARM_M` of it in the world, and its world centre;
- ``frames``: the distance travelled, false alarms on and off the track as the detection campaign
  counts them (blobs touching neither a pit nor the track-border band), and the grid's area per
  terrain class and distance bin (what the false-alarm rates divide by).

The rows go through :func:`~negobs_gym.eval.campaign.run_campaign` (progress bar, resume after a
kill, ``--workers``/``--ray``, byte-identical CSVs).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

from negobs_gym.core.geometry import distance_to_polyline, vehicle_to_world_xy
from negobs_gym.core.pose import Pose
from negobs_gym.envs.pem import (
    PEM_CHANNELS,
    TERRAIN_CLASSES,
    PemGrid,
    PerceptionErrorModel,
    channel_outlines,
    class_raster,
    clutter_distance_m,
    outline_boxes,
    outline_distance_m,
    rasterise_outlines,
)
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.campaign import Episode, Rows, RunOptions, format_row, run_campaign
from negobs_gym.eval.detection import track_border_mask, world_outline_to_vehicle
from negobs_gym.eval.detection_campaign import FRAME_S, SETTLE_S, DetectionCampaignConfig, detection_course
from negobs_gym.spec import ObservationConfig

__all__ = [
    "CHANNEL_TABLES",
    "DISTANCE_EDGES_M",
    "FRAME_COLUMNS",
    "MODES",
    "SIGHTING_COLUMNS",
    "SPURIOUS_COLUMNS",
    "PemCampaignConfig",
    "path_steering",
    "pem_digest",
    "run_pem_campaign",
]

#: The grids judged: the detector's and the PEM's.
MODES = ("detector", "pem")
#: 2 m distance bins from the vehicle origin, to the grid's farthest corner (~26.4 m).
DISTANCE_EDGES_M: tuple[float, ...] = tuple(float(d) for d in range(0, 30, 2))
#: A spurious blob within this of one in the frame before (world centres) is the same false alarm
#: [m]: what the INS drift and a blob's outline, growing as the car nears it, move its centre.
SAME_ALARM_M = 1.0
#: How far from a positive obstacle a spurious blob's ``clutter_m`` is recorded [m].
CLUTTER_REACH_M = 8.0
#: How far from a pit's rim a spurious blob's ``pit_m`` is recorded [m].
PIT_REACH_M = 3.0

SIGHTING_COLUMNS = (
    "episode",
    "seed",
    "frame",
    "mode",
    "obstacle",
    "cells",
    "depth_m",
    "centre_m",
    "detected",
    "drawn_cells",
    "near_offset_m",
    "far_offset_m",
)
SPURIOUS_COLUMNS = (
    "episode",
    "seed",
    "frame",
    "mode",
    "terrain_class",
    "edge_m",
    "distance_m",
    "cells",
    "rows",
    "cols",
    "on_border",
    "seen_before",
    "clutter_m",
    "pit_m",
    "x_m",
    "y_m",
)
AREA_COLUMNS = tuple(f"area_{c}_{k}" for c in TERRAIN_CLASSES for k in range(len(DISTANCE_EDGES_M) - 1))
FRAME_COLUMNS = (
    "episode",
    "seed",
    "frame",
    "mode",
    "travelled_m",
    "false_alarms_on",
    "false_alarms_off",
    *AREA_COLUMNS,
)
#: The tables of each channel: ``sightings``, ``spurious``, ``frames`` (``negative``) and the same
#: prefixed ``positive_``.
CHANNEL_TABLES: dict[str, dict[str, str]] = {
    c: {t: (t if c == "negative" else f"{c}_{t}") for t in ("sightings", "spurious", "frames")}
    for c in PEM_CHANNELS
}


def _course_default() -> DetectionCampaignConfig:
    return DetectionCampaignConfig(seeds=1, frames=1)


@dataclass(frozen=True, kw_only=True)
class PemCampaignConfig:
    """What a PEM fit or check drives.

    Attributes:
        seeds: Courses (seeds ``first_seed`` .. ``first_seed + seeds - 1``).
        first_seed: The first course's seed (a check takes seeds the fit never drove).
        frames: Frames of the whole run, split evenly over the courses.
        observation: The detector grid's settings (the env's default: ``ObservationConfig()``);
            its ``source`` is ignored, the detector is always run.
        course: The detection campaign's course settings (pit mix, clutter, speeds); its seeds,
            frames and rig are not used.
        border_band_m: Width of the ``verge`` terrain class beyond each track edge [m], where a
            detector draws the real drops at the track's edge (not in paper N).
        clutter_band_m: Reach of the ``clutter`` and ``mound`` terrain classes around a positive
            obstacle's footprint [m]: the detector's false alarms beside the verge clutter lie on or
            within 0.5 m of it (docs/pem.md; not in paper N).
        rough_relief_m: Ground relief within 1 m from which off-track ground is ``rough`` [m]: the
            detector's false alarms away from the clutter lie on such ground five times as often
            as on the rest (docs/pem.md; not in paper N).
        track_obstacles_per_100m: Rocks and boxes added on the track per 100 m, beside the car's
            path (what paper T's LUX channel is fitted on; not in either paper). 0: none.
        track_obstacle_kinds: Their kinds, drawn evenly.
        track_obstacle_lateral_m: Range of their centres' distance from the centre line [m]: a
            box's inner side ~0.4 m beyond the car's (2 m wide) on the centre line.
        track_obstacle_gap_m: Least distance along the track from a pit on the same side [m].
        positive_match_cells: Cells the positive obstacles' footprints are grown by when matching
            the ``positive`` layer's blobs (the LUX's returns lie on a face, on the footprint's
            edge, a cell centre often just outside it).
        path_offset_m: The car's path's signed offset from the centre line [m] (> 0 towards +x of
            the course); 0, the centre line, is what the fit and check drive.
        pit_fragment_m: A ``negative`` blob touching no pit whose centre lies this close to a
            pit's rim [m] is a fragment of that pit's drawing, not a false alarm: the fit leaves
            it out of the false-alarm tables. Paper N's detector draws a pit up to ~0.6 m larger
            than it is, and beside the car, where the rim enters the HDL-64's ring-free disc, the
            drawing splits; on the detection courses every blob within 6 m of the car that
            touched no pit lay 0.2-0.9 m from one (docs/pem.md; not in paper N).
    """

    seeds: int = 8
    first_seed: int = 0
    frames: int = 400
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    course: DetectionCampaignConfig = field(default_factory=_course_default)
    border_band_m: float = 1.0
    clutter_band_m: float = 0.6
    rough_relief_m: float = 0.2
    track_obstacles_per_100m: float = 6.0
    track_obstacle_kinds: tuple[str, ...] = ("rock", "box")
    track_obstacle_lateral_m: tuple[float, float] = (1.9, 2.6)
    track_obstacle_gap_m: float = 3.0
    positive_match_cells: int = 2
    path_offset_m: float = 0.0
    pit_fragment_m: float = 1.0

    def __post_init__(self) -> None:
        require(
            type(self.seeds) is int and self.seeds >= 1, "seeds", f"must be an int >= 1, got {self.seeds!r}"
        )
        require(type(self.first_seed) is int and self.first_seed >= 0, "first_seed", "must be an int >= 0")
        require(
            type(self.frames) is int and self.frames >= self.seeds,
            "frames",
            f"must be an int >= seeds ({self.seeds}), got {self.frames!r}",
        )
        require(
            isinstance(self.observation, ObservationConfig), "observation", "must be an ObservationConfig"
        )
        for name in ("border_band_m", "clutter_band_m", "rough_relief_m", "track_obstacles_per_100m",
                     "track_obstacle_gap_m", "pit_fragment_m"):  # fmt: skip
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, name, f"must be >= 0, got {value!r}")
        lo, hi = self.track_obstacle_lateral_m
        require(
            0 <= lo <= hi,
            "track_obstacle_lateral_m",
            f"must be (low, high), 0 <= low <= high, got {(lo, hi)}",
        )
        require(
            math.isfinite(self.path_offset_m), "path_offset_m", f"must be finite, got {self.path_offset_m!r}"
        )
        require(
            self.pit_fragment_m <= PIT_REACH_M,
            "pit_fragment_m",
            f"must be <= {PIT_REACH_M} m (how far the rows record pit_m), got {self.pit_fragment_m!r}",
        )
        require(len(self.track_obstacle_kinds) > 0, "track_obstacle_kinds", "must name at least one kind")
        require(
            type(self.positive_match_cells) is int and self.positive_match_cells >= 0,
            "positive_match_cells",
            f"must be an int >= 0, got {self.positive_match_cells!r}",
        )

    @property
    def seed_list(self) -> list[int]:
        return list(range(self.first_seed, self.first_seed + self.seeds))

    def frames_of(self, index: int) -> int:
        base, extra = divmod(self.frames, self.seeds)
        return base + (1 if index < extra else 0)

    def track_obstacles(self, seed: int, length_m: float, pits: tuple) -> list:
        """The rocks and boxes a course adds on its track (``PositiveObstacleSpec``), away from its pits."""
        from negobs_gym.sim.carving import PositiveObstacleSpec

        layout = np.random.default_rng([seed, 7])
        out = []
        for _ in range(round(self.track_obstacles_per_100m * length_m / 100.0)):
            station = float(layout.uniform(10.0, length_m - 5.0))
            lateral = float(layout.choice([-1.0, 1.0]) * layout.uniform(*self.track_obstacle_lateral_m))
            kind = str(layout.choice(list(self.track_obstacle_kinds)))
            clear = all(
                abs(station - pit.station_m) >= self.track_obstacle_gap_m or pit.lateral_m * lateral < 0
                for pit in pits
            )
            if clear:
                out.append(PositiveObstacleSpec(kind=kind, station_m=station, lateral_m=lateral))
        return out


#: Version of the judge's rules (:func:`blob_counts`, :class:`_Judge`). Every drive's part file
#: records it, so resuming into drives judged by other rules is an error naming it, never a silent
#: mix of the two (1: a blob counts for every obstacle it touches; 3: for the obstacles that own
#: one of its cells; 4: the spurious rows record ``pit_m``).
JUDGE_VERSION = 4


def pem_digest(model_text: str) -> str:
    """SHA-256 of a PEM file's text and of the code that draws and judges its grids
    (:mod:`negobs_gym.envs.pem`, this module): a resumed check reruns the PEM's drives after either
    changes, and keeps the detector's."""
    from negobs_gym.envs import pem

    digest = hashlib.sha256(model_text.encode("utf-8"))
    for module in (pem.__file__, __file__):
        digest.update(Path(module).read_bytes())
    return digest.hexdigest()


def episodes(config: PemCampaignConfig, model: PerceptionErrorModel | None) -> list[Episode]:
    """Per seed a detector episode, and with ``model`` a PEM episode keyed by :func:`pem_digest`
    (the model's JSON text and :data:`JUDGE_VERSION` ride along, so a resume checks them too)."""

    def args(i: int, seed: int, pem: str | None) -> dict:
        frames = config.frames_of(i)
        return {"config": config, "seed": seed, "frames": frames, "pem": pem, "judge": JUDGE_VERSION}

    out = [Episode(f"seed{seed:07d}", args(i, seed, None)) for i, seed in enumerate(config.seed_list)]
    if model is not None:
        text = model.to_json()
        digest = pem_digest(text)[:12]
        out += [
            Episode(f"seed{seed:07d}-pem-{digest}", args(i, seed, text))
            for i, seed in enumerate(config.seed_list)
        ]
    return out


def blob_counts(labels: np.ndarray, count: int, truths: list[np.ndarray], match_cells: int) -> np.ndarray:
    """(len(truths), count + 1) bool: whether blob label b (0 = background, never) counts as drawing
    obstacle i. Each cell inside some obstacle's mask grown by ``match_cells`` belongs to one
    obstacle: the smallest whose own mask holds it, else the smallest whose grown mask does; a
    blob counts for every obstacle that owns one of its cells. So a rock's face drawn on the mound
    it lies on is the rock's alone, while a blob that spans a rock and the mound beside it, or two
    pits, counts for both, as each obstacle's own drawing would."""
    counts = np.zeros((len(truths), count + 1), dtype=bool)
    if not truths or not count:
        return counts
    owner = np.full(labels.shape, -1, dtype=np.int64)
    by_size = sorted(range(len(truths)), key=lambda i: -int(truths[i].sum()))  # smaller ones last
    grown = [ndimage.binary_dilation(t, iterations=match_cells) if match_cells else t for t in truths]
    for masks in (grown, truths):  # an own mask beats a grown one
        for i in by_size:
            owner[masks[i]] = i
    cells = (owner >= 0) & (labels > 0)
    counts[owner[cells], labels[cells]] = True
    return counts


@dataclass
class _Judge:
    """Judges one grid's layers of one channel frame by frame (keeps its last spurious blobs).

    ``match_cells``: the truth's cells grown by this many when matching blobs to it."""

    mode: str
    channel: str = "negative"
    match_cells: int = 0
    previous: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    def frame(self, layer, ctx) -> tuple[list[str], list[str], tuple[int, int]]:
        labels, count = ndimage.label(layer, structure=np.ones((3, 3), dtype=bool))
        sightings, spurious = [], []
        truths = ctx.truths[self.channel]
        counts = blob_counts(labels, count, [truth for _, truth in truths], self.match_cells)
        on_truth = counts.any(axis=0)
        for index, (k, truth) in enumerate(truths):
            hit = np.flatnonzero(counts[index])
            size = ctx.depths[self.channel][k]
            row = [
                ctx.key,
                ctx.seed,
                ctx.frame,
                self.mode,
                k,
                int(truth.sum()),
                size,
                ctx.centre_m[self.channel][k],
            ]
            if hit.size:
                drawn = np.isin(labels, hit)
                r_t, r_d = ctx.range_m[truth], ctx.range_m[drawn]
                row += [True, int(drawn.sum()), float(r_d.min() - r_t.min()), float(r_d.max() - r_t.max())]
            else:
                row += [False, 0, math.nan, math.nan]
            sightings.append(format_row(row))
        centres, fa_on, fa_off = [], 0, 0
        if count:
            index = np.arange(1, count + 1)
            cells = ndimage.sum_labels(np.ones_like(labels), labels, index).astype(np.int64)
            xs = ndimage.mean(ctx.centres[..., 0], labels, index)
            ys = ndimage.mean(ctx.centres[..., 1], labels, index)
            border = ndimage.maximum(ctx.border.astype(np.uint8), labels, index).astype(bool)
            boxes = ndimage.find_objects(labels)
            blobs = np.flatnonzero(~on_truth[1:])
            worlds = vehicle_to_world_xy(
                np.column_stack([xs[blobs], ys[blobs]]).reshape(-1, 2), (ctx.pose.x, ctx.pose.y), ctx.pose.yaw
            )
            klasses = ctx.classes.at(worlds)
            clutters = clutter_distance_m(worlds, ctx.terrain.positive_obstacles, CLUTTER_REACH_M)
            pits = outline_distance_m(worlds, ctx.outlines["negative"], PIT_REACH_M)
            for i, j in enumerate(blobs.tolist()):
                local = np.array([[xs[j], ys[j]]])
                world = worlds[i]
                klass, clutter, pit = int(klasses[i]), float(clutters[i]), float(pits[i])
                seen = (
                    bool(len(self.previous))
                    and float(np.min(np.hypot(*(self.previous - world).T))) <= SAME_ALARM_M
                )
                centres.append(world)
                dist = float(math.hypot(xs[j], ys[j]))
                lateral = float(distance_to_polyline(local, ctx.centre_line)[0])
                r, c = np.nonzero(labels[boxes[j]] == j + 1)
                row = [
                    ctx.key,
                    ctx.seed,
                    ctx.frame,
                    self.mode,
                    TERRAIN_CLASSES[klass],
                    lateral - 0.5 * ctx.width_m,
                ]
                row += [
                    dist,
                    int(cells[j]),
                    int(r.max() - r.min() + 1),
                    int(c.max() - c.min() + 1),
                    border[j],
                    seen,
                    clutter if math.isfinite(clutter) else "",
                    pit if math.isfinite(pit) else "",
                    float(world[0]),
                    float(world[1]),
                ]
                spurious.append(format_row(row))
                if not border[j]:  # the detection campaign's false alarm (paper N §4.2)
                    on = lateral <= 0.5 * ctx.width_m
                    fa_on, fa_off = fa_on + on, fa_off + (not on)
        self.previous = np.array(centres).reshape(-1, 2)
        return sightings, spurious, (fa_on, fa_off)


@dataclass
class _Frame:
    """What both grids of one frame are judged against (``truths``, ``centre_m`` and ``depths``
    per channel: each true obstacle's full-grid mask, centre distance, and depth or height)."""

    key: str
    seed: int
    frame: int
    terrain: object
    pose: object
    truths: dict
    centre_m: dict
    depths: dict
    range_m: np.ndarray
    centres: np.ndarray
    border: np.ndarray
    centre_line: np.ndarray
    classes: object
    width_m: float
    outlines: dict


def path_steering(pose: Pose, line: np.ndarray, offset_m: float = 0.0) -> float:
    """The courses' P-controller: the steering command [-1, 1] back to the centre line ``line``
    (N, 2), shifted by ``offset_m`` along +x (the detection courses run along +y), and to its heading."""
    lateral = pose.x - float(np.interp(pose.y, line[:, 1], line[:, 0])) - offset_m
    return float(np.clip(0.5 * lateral - 2.0 * pose.yaw, -1.0, 1.0))


def run_episode(episode: Episode) -> Rows:
    """Drive one course through the detector grid, or with a PEM (``pem`` given) through its grids;
    its ``sightings``, ``spurious`` and ``frames`` rows (module docstring)."""
    from negobs_gym.envs.perception import DetectorGrid
    from negobs_gym.sim.vehicle import Vehicle
    from negobs_gym.sim.world import World

    cfg: PemCampaignConfig = episode.args["config"]
    seed, n_frames = int(episode.args["seed"]), int(episode.args["frames"])
    pem_text = episode.args["pem"]
    model = PerceptionErrorModel.from_json(pem_text) if pem_text is not None else None
    course = cfg.course
    speed = float(np.random.default_rng([seed, 1]).uniform(course.min_speed_mps, course.max_speed_mps))
    length_m = speed * FRAME_S * n_frames + 35.0
    terrain = detection_course(
        course, seed, length_m, extra_positives=lambda pits: cfg.track_obstacles(seed, length_m, pits)
    )
    observation = dataclasses.replace(cfg.observation, source="detector")
    grid = observation.grid
    centres = grid.cell_centres()
    range_m = np.hypot(centres[..., 0], centres[..., 1])
    line = np.asarray(terrain.track.centreline_xy_m, dtype=np.float64)
    step = max(1, round(1.0 / max(float(np.median(np.diff(terrain.track.stations_m))), 1e-3)))
    line = np.vstack([line[::step], line[-1:]])
    outlines = {c: channel_outlines(terrain, c) for c in PEM_CHANNELS}
    boxes = {c: outline_boxes(outlines[c]) for c in PEM_CHANNELS}
    depths = {
        "negative": [o.depth_m for o in terrain.negative_obstacles],
        "positive": [2.0 * float(o.half_extents_m[2]) for o in terrain.positive_obstacles],
    }
    cache: dict = {}  # the terrain's class raster, built once for the judges and both PEM channels
    raster = class_raster(terrain, cfg.border_band_m, cfg.clutter_band_m, cfg.rough_relief_m, cache)
    width = terrain.track.width_m
    bins = len(DISTANCE_EDGES_M) - 1
    dist_bin = np.clip(np.digitize(range_m, DISTANCE_EDGES_M) - 1, 0, bins - 1).ravel()
    modes = ("pem",) if model is not None else ("detector",)
    match = {"negative": 0, "positive": cfg.positive_match_cells}
    judges = {(c, m): _Judge(m, c, match[c]) for c in PEM_CHANNELS for m in modes}
    rows: Rows = {name: [] for tables in CHANNEL_TABLES.values() for name in tables.values()}
    with World(terrain) as world:
        vehicle = Vehicle(world, rng=np.random.default_rng([seed, 3]))
        detector = None
        if model is None:
            detector = DetectorGrid(observation, world, vehicle, np.random.default_rng([seed, 5]))
        pems = {}
        if model is not None:
            pem_rng = np.random.default_rng([seed, 6])
            pems = {
                c: PemGrid(
                    model, grid, terrain, pem_rng if c == "negative" else pem_rng.spawn(1)[0], cache, c
                )
                for c in model.channels
            }
        steps = round(FRAME_S / world.config.time_step_s)
        world.step(round(SETTLE_S / world.config.time_step_s))
        last = vehicle.true_pose()
        for frame in range(n_frames):
            vehicle.apply(0.0, 0.0, path_steering(last, line, cfg.path_offset_m))
            vehicle.set_speed(speed)
            world.step(steps)
            pose = vehicle.true_pose()
            layers = {}
            if detector is not None:
                observed = detector.observe(world.sim_time_s)
                layers = {(c, "detector"): observed[c] for c in PEM_CHANNELS}
            for c, pem in pems.items():
                layers[(c, "pem")] = pem.layer(pose)
            travelled = math.hypot(pose.x - last.x, pose.y - last.y)
            last = pose
            truths = {}
            for c in PEM_CHANNELS:
                truths[c] = []
                for k, mask, rows_, cols_ in rasterise_outlines(outlines[c], pose, grid, boxes[c]):
                    full = np.zeros(grid.shape, dtype=bool)
                    full[rows_, cols_] = mask
                    truths[c].append((k, full))
            centre_m = {
                c: {k: float(np.hypot(*centres[m].mean(axis=0))) for k, m in truths[c]} for c in PEM_CHANNELS
            }
            centre_line = world_outline_to_vehicle(line, pose)
            world_cells = vehicle_to_world_xy(centres.reshape(-1, 2), (pose.x, pose.y), pose.yaw)
            classes = raster.at(world_cells)
            area = np.zeros((len(TERRAIN_CLASSES), bins))
            np.add.at(area, (classes, dist_bin), grid.cell_m**2)
            ctx = _Frame(
                episode.key, seed, frame, terrain, pose, truths, centre_m, depths, range_m, centres,
                track_border_mask(centre_line, width, grid, course.matching.border_band_m),
                centre_line, raster, width, outlines,
            )  # fmt: skip
            for (channel, mode), judge in judges.items():
                if (channel, mode) not in layers:  # a PEM without this channel
                    continue
                tables = CHANNEL_TABLES[channel]
                sightings, spurious, (fa_on, fa_off) = judge.frame(layers[(channel, mode)], ctx)
                rows[tables["sightings"]] += sightings
                rows[tables["spurious"]] += spurious
                rows[tables["frames"]].append(
                    format_row(
                        [episode.key, seed, frame, mode, travelled, fa_on, fa_off, *area.ravel().tolist()]
                    )
                )
    return rows


def run_pem_campaign(
    config: PemCampaignConfig,
    out_dir: str | Path,
    model: PerceptionErrorModel | None = None,
    options: RunOptions | None = None,
    description: str = "PEM courses",
) -> dict[str, Path]:
    """Drive the courses (resumable, on workers or Ray); the CSVs of :data:`CHANNEL_TABLES` in
    ``out_dir``. With ``model``, its grids are judged beside the detector's."""
    if model is not None and not isinstance(model, PerceptionErrorModel):
        raise ConfigError("model", "must be a PerceptionErrorModel")
    columns = {"sightings": SIGHTING_COLUMNS, "spurious": SPURIOUS_COLUMNS, "frames": FRAME_COLUMNS}
    tables = {name: columns[t] for names in CHANNEL_TABLES.values() for t, name in names.items()}
    return run_campaign(run_episode, episodes(config, model), out_dir, tables, options, description)
