"""A perception-error model (PEM) of the detector grid's obstacle channels, at the oracle's cost.

Paper N's detector (cast rig, pair tests, fusion) and paper T's (the bumper LUX) cost most of a
detector-grid step. The PEM reproduces their output from the ground truth instead, as PEMs for AV
virtual testing do (Piazzoni et al., IEEE T-ITS 2023). Each channel it models (:data:`PEM_CHANNELS`:
``negative``, paper N's pits; ``positive``, paper T's obstacles) has its own tables: every frame
each true obstacle of the channel on the grid (a pit's rim, a positive obstacle's footprint) is
rasterised like the oracle's and then, by parametric tables fitted on the detector
(:mod:`negobs_gym.eval.pem_fit`),

- is drawn or missed: P(drawn) by its size (cells) and centre distance (2 m bins) and by its state,
  a three-state Markov chain: never drawn yet (the first confirmation: a distance for one that
  comes from beyond the detector's reach, a latency for one first seen within it), drawn last frame
  (persistence; 1 - it is the dropout, the close-range one in the HDL-64's ring-free disc too) and
  drawn before but not last frame (re-acquisition); where the tables hold a loss distance (paper
  T's LUX: its four layers pass over an obstacle at a distance set by its height), an obstacle
  nearer than its own is never drawn again;
- when drawn, its cells are those of the true rim inside its bearing span between the true near
  edge plus a near-edge offset (rounded to the nearest cell's range) and the far edge plus a
  far-edge offset (the extent error), both drawn from the fitted quantiles of their distance bin;
- false alarms: spurious blobs, fixed in the world, born at a rate per m² by terrain class
  (:data:`TERRAIN_CLASSES`: the track, the verge band beside it, the bank, drop-off or rough
  ground beyond, and clutter: the ground near a positive obstacle) and distance, kept from one
  frame to the next with a fitted probability, of a fitted size, and clear of the channel's true
  obstacles (a blob touching one is a drawing of it, and the fit counted none of those).

The parameters are a :class:`PemParameters`; a :class:`PerceptionErrorModel` adds the detector,
rig and observation settings it was fitted on (:func:`pem_settings`) and is saved as a versioned
JSON file. :func:`load_pem` refuses a file whose settings differ from the observation's, naming
each difference. A model for each ``positive`` channel ships (:data:`SHIPPED_PEM_PATHS`), the
default fitted on the envs' default detector grid (docs/pem.md).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from negobs_gym.core.files import write_text_atomic
from negobs_gym.core.geometry import (
    lattice_in_polygon,
    points_in_polygon,
    polyline_stations,
    vehicle_to_world_xy,
    world_to_vehicle_xy,
)
from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, require
from negobs_gym.sim.types import PositiveObstacle, Terrain
from negobs_gym.spec import ObservationConfig

__all__ = [
    "DEFAULT_PEM_PATH",
    "PEM_CHANNELS",
    "PEM_FORMAT",
    "PEM_VERSION",
    "SHIPPED_PEM_PATHS",
    "TERRAIN_CLASSES",
    "ClassRaster",
    "PemGrid",
    "PemParameters",
    "PerceptionErrorModel",
    "bin_index",
    "class_raster",
    "clutter_distance_m",
    "fallback_chain",
    "ground_relief_m",
    "load_pem",
    "pem_settings",
    "shipped_pem_path",
    "terrain_classes",
]

PEM_FORMAT = "negobs_gym.pem"
#: Version of the file layout; a file of another version is refused.
PEM_VERSION = 5
#: The detector grid's channels a PEM models: ``negative`` (paper N's detector) and ``positive``
#: (what ``ObservationConfig.positive_detector`` names: paper T's LUX obstacles or the structure
#: channel; a file models the one it was fitted on).
PEM_CHANNELS: tuple[str, ...] = ("negative", "positive")
_DATA = Path(__file__).with_name("data")
#: The shipped PEMs by the ``positive`` channel they model (``ObservationConfig.positive_detector``):
#: ``traversable``, fitted on the envs' default detector grid (``ObservationConfig()``), and
#: ``structure``, fitted on the scenario ``offroad_nav_v2_structure``'s (the structure channel held 2 s).
SHIPPED_PEM_PATHS: dict[str, Path] = {
    "traversable": _DATA / "pem_default.json",
    "structure": _DATA / "pem_structure.json",
}
#: The PEM fitted on the envs' default detector grid, shipped.
DEFAULT_PEM_PATH = SHIPPED_PEM_PATHS["traversable"]
#: Terrain classes the false-alarm rates are kept for (:class:`ClassRaster`): ``track`` (within half
#: its width of the centre line); off the track, ``clutter`` (within ``clutter_band_m`` of a
#: standing positive obstacle's footprint: rocks, boxes, vehicles) and ``mound`` (of one raised
#: into the ground: mounds), whichever is nearer; else ``verge`` (the band ``border_band_m`` beyond
#: an edge) and beyond it the side's border kind (the terrain record's ``Track.border_kinds``):
#: ``bank``, ``dropoff``, or where the side is a plain verge ``rough`` ground (its heights span
#: ``rough_relief_m`` or more within :data:`RELIEF_WINDOW_M`: bumps and the dips behind them) or
#: ``smooth`` ground.
TERRAIN_CLASSES: tuple[str, ...] = (
    "track",
    "verge",
    "bank",
    "dropoff",
    "smooth",
    "rough",
    "clutter",
    "mound",
)
#: Where a class's false alarms are placed: moved across the track to a copied blob's distance
#: from the edge (the track-bound classes), or where born (near their obstacle, on their ground).
_PLACED_BY_EDGE = np.array([c in ("track", "verge", "bank", "dropoff", "smooth") for c in TERRAIN_CLASSES])
#: A class with no area in a fit borrows this class's rates and blobs (that one too none: ``smooth``'s).
FALLBACK_CLASS: dict[str, str] = {
    "verge": "smooth",
    "bank": "smooth",
    "dropoff": "smooth",
    "smooth": "rough",
    "rough": "smooth",
    "clutter": "mound",
    "mound": "clutter",
}
#: Side of the square window a point's ground relief (highest minus lowest height) is taken over [m].
RELIEF_WINDOW_M = 1.0


def fallback_chain(name: str) -> tuple[str, ...]:
    """The classes a class without data borrows from, in order (:data:`FALLBACK_CLASS`, then ``smooth``)."""
    first = FALLBACK_CLASS.get(name)
    return tuple(c for c in (first, "smooth") if c is not None and c != name)


#: cell of the terrain-class raster [m]
CLASS_RASTER_M = 0.4
#: States of a pit in the PEM's chain (``GONE``: nearer than its loss distance, never drawn again).
NEVER, DRAWN, LOST, GONE = 0, 1, 2, 3
_STATE_NAMES = ("p_keep", "p_return")
#: spacing of the centre-line samples the terrain classes are measured to [m]
_TRACK_SPACING_M = 0.1
#: a drawn pit's rim is at most this many cells beyond the true one (caps a wild offset draw)
_MAX_GROW_CELLS = 10
#: false alarms are placed on blocks of this many cells a side (their class and distance per block)
_BLOCK_CELLS = 4
#: a new false alarm that touches a true obstacle is moved up to this many times (else dropped)
_PLACE_TRIES = 8
#: 8-connectivity, as the detectors' clusters and the check's blobs
_EIGHT = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True, kw_only=True)
class PemParameters:
    """The fitted tables. Indices: ``[size bin][distance bin]`` for the pits' chain,
    ``[size bin][quantile]`` for the first confirmation, ``[distance bin][quantile]`` for the
    offsets, ``[class][distance bin]`` for the false alarms.

    Attributes:
        distance_edges_m: Edges of the distance bins [m] (a pit's cell centres' mean, a false
            alarm's centre, from the vehicle origin; paper N §4.2's distance); beyond the last
            edge counts in the last bin.
        size_edges_cells: Edges of the size bins (a pit's rim cells on the 20 cm grid).
        quantile_levels: Levels of every quantile table, 0 to 1.
        confirm_distance_m: Quantiles per size bin (the whole rim's cells) of the centre distance
            at which a pit that came onto the grid from beyond the detector's reach was first
            drawn [m]; -1 stands for a pit passed undrawn. Each pit draws one at its first
            sighting.
        confirm_latency_frames: Quantiles of the frames from a pit's first sighting to its first
            drawing, of pits first seen within ``approach_m`` (an episode's start: the fusion needs
            hits from several frames). A pit first seen beyond ``approach_m`` is first drawn within
            its drawn distance, one first seen nearer once it is also seen for its drawn latency.
        approach_m: A pit first seen (its centre) at least this far came from beyond the
            detector's reach [m].
        loss_distance_m: Quantiles per size bin (the whole outline's cells) of the centre distance
            at which an obstacle passed on its approach was last drawn [m]; nearer than its own
            draw, an obstacle is never drawn again. Empty: obstacles are not lost by distance
            (the pits: paper N's fusion keeps a pit drawn to the car).
        p_keep: P(drawn) of a pit drawn in the frame before.
        p_return: P(drawn) of a pit drawn before, but not in the frame before.
        sightings: Frames behind each ``[size][distance]`` entry of the chain (all states).
        near_offset_m: Quantiles per size bin (the cells in view) and distance bin of the drawn
            near edge minus the true one (range from the vehicle origin) [m]: > 0 drawn farther
            than it is. A table per distance bin only (a file fitted before the size axis)
            serves every size.
        far_offset_m: The same of the far edge [m].
        fa_density_per_m2: Mean false alarms per frame per m² of the class and distance bin.
        fa_area_m2: The grid area per class the fit saw, summed over its frames [m²]; a class
            with none takes its :data:`FALLBACK_CLASS`'s rates (not fitted, shown by the 0).
        fa_keep: P(a false alarm is still there the next frame), per class and the distance bin
            it is in then.
        fa_blobs: The detector's false alarms a new one copies, each ``(class, distance bin,
            edge_m, rows, cols, cells)``: ``edge_m`` is its centre's distance from the nearer
            track edge (< 0 on the track), ``rows`` x ``cols`` its box (along x across the
            vehicle), ``cells`` its size.
        border_band_m: Width of the ``verge`` class beyond each track edge [m].
        clutter_band_m: Reach of the ``clutter`` and ``mound`` classes around a positive
            obstacle's footprint [m].
        rough_relief_m: Ground relief from which off-track ground is ``rough`` [m].
        match_cells: A blob within this many cells of a true obstacle counted as drawing it in
            the fit, not as a false alarm; the model's false alarms keep that far from them.
    """

    distance_edges_m: tuple[float, ...]
    size_edges_cells: tuple[float, ...]
    quantile_levels: tuple[float, ...]
    confirm_distance_m: tuple[tuple[float, ...], ...]
    confirm_latency_frames: tuple[float, ...]
    approach_m: float
    loss_distance_m: tuple[tuple[float, ...], ...]
    p_keep: tuple[tuple[float, ...], ...]
    p_return: tuple[tuple[float, ...], ...]
    sightings: tuple[tuple[int, ...], ...]
    near_offset_m: tuple[tuple[tuple[float, ...], ...], ...] | tuple[tuple[float, ...], ...]
    far_offset_m: tuple[tuple[tuple[float, ...], ...], ...] | tuple[tuple[float, ...], ...]
    fa_density_per_m2: tuple[tuple[float, ...], ...]
    fa_area_m2: tuple[float, ...]
    fa_keep: tuple[tuple[float, ...], ...]
    fa_blobs: tuple[tuple[float, ...], ...]
    border_band_m: float
    clutter_band_m: float
    rough_relief_m: float
    match_cells: int

    def __post_init__(self) -> None:
        nd, ns = len(self.distance_edges_m) - 1, len(self.size_edges_cells) - 1
        require(nd >= 1 and ns >= 1, "distance_edges_m", "needs at least two distance and size edges")
        for name in ("distance_edges_m", "size_edges_cells", "quantile_levels"):
            edges = np.asarray(getattr(self, name), dtype=np.float64)
            require(bool(np.all(np.diff(edges) > 0)), name, "must be strictly increasing")
        for name in (*_STATE_NAMES, "sightings"):
            table = np.asarray(getattr(self, name), dtype=np.float64)
            require(
                table.shape == (ns, nd), name, f"must be {ns} x {nd} (sizes x distances), got {table.shape}"
            )
        for name in _STATE_NAMES:
            table = np.asarray(getattr(self, name), dtype=np.float64)
            require(bool(np.all((table >= 0) & (table <= 1))), name, "probabilities must lie in [0, 1]")
        nq = len(self.quantile_levels)
        shapes = {
            "confirm_distance_m": (ns, nq),
            "confirm_latency_frames": (nq,),
            "near_offset_m": (ns, nd, nq),
            "far_offset_m": (ns, nd, nq),
        }
        for name, shape in shapes.items():
            table = np.asarray(getattr(self, name), dtype=np.float64)
            ok = table.shape == shape or (name.endswith("_offset_m") and table.shape == shape[1:])
            require(ok, name, f"must have shape {shape}, got {table.shape}")
            require(bool(np.all(np.diff(table, axis=-1) >= 0)), name, "quantiles must not decrease")
        require(min(self.confirm_latency_frames) >= 0, "confirm_latency_frames", "must be >= 0")
        loss = np.asarray(self.loss_distance_m, dtype=np.float64)
        if loss.size:
            require(
                loss.shape == (ns, nq), "loss_distance_m", f"must be empty or {(ns, nq)}, got {loss.shape}"
            )
            require(
                bool(np.all(np.diff(loss, axis=-1) >= 0)), "loss_distance_m", "quantiles must not decrease"
            )
            require(bool(np.all(loss >= 0)), "loss_distance_m", "distances must be >= 0")
        require(
            isinstance(self.match_cells, int)
            and not isinstance(self.match_cells, bool)
            and self.match_cells >= 0,
            "match_cells",
            f"must be a whole number of cells >= 0, got {self.match_cells!r}",
        )
        density = np.asarray(self.fa_density_per_m2, dtype=np.float64)
        nc = len(TERRAIN_CLASSES)
        require(density.shape == (nc, nd), "fa_density_per_m2", f"must be {nc} x {nd}, got {density.shape}")
        require(bool(np.all(density >= 0)), "fa_density_per_m2", "must be >= 0")
        keep = np.asarray(self.fa_keep, dtype=np.float64)
        require(
            keep.shape == (nc, nd) and bool(np.all((keep >= 0) & (keep < 1))),
            "fa_keep",
            f"must be {nc} x {nd} values in [0, 1)",
        )
        area = np.asarray(self.fa_area_m2, dtype=np.float64)
        require(area.shape == (nc,) and bool(np.all(area >= 0)), "fa_area_m2", f"must be {nc} values >= 0")
        blobs = np.asarray(self.fa_blobs, dtype=np.float64).reshape(-1, 6)
        require(
            bool(np.all((blobs[:, 0] >= 0) & (blobs[:, 0] < nc) & (blobs[:, 1] >= 0) & (blobs[:, 1] < nd)))
            and bool(np.all(blobs[:, 3:] >= 1)),
            "fa_blobs",
            "each must be (class, distance bin, edge_m, rows, cols, cells) with rows, cols, cells >= 1",
        )
        require(
            len(blobs) > 0 or not density.any(),
            "fa_blobs",
            "must hold at least one blob when false alarms occur",
        )
        for name in ("approach_m", "border_band_m", "clutter_band_m", "rough_relief_m"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, name, f"must be >= 0, got {value!r}")

    def to_dict(self) -> dict[str, Any]:
        return json.loads(json.dumps(dataclasses.asdict(self)))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PemParameters:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown, missing = set(data) - names, names - set(data)
        require(
            not unknown and not missing, "parameters", f"unknown {sorted(unknown)}, missing {sorted(missing)}"
        )
        return cls(**{k: _tuples(v) for k, v in data.items()})


def _tuples(value: Any) -> Any:
    """JSON lists as (nested) tuples, for the frozen dataclass."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


@dataclass(frozen=True, kw_only=True)
class PerceptionErrorModel:
    """A PEM: its parameters per channel, the settings it was fitted on (:func:`pem_settings`) and how.

    ``parameters`` model the ``negative`` channel; ``positive``, when given, the ``positive``
    channel (else an env draws the oracle's there). ``fit`` records the fitting run (seeds, frames,
    course) so that a check can refuse its seeds.
    """

    parameters: PemParameters
    positive: PemParameters | None = None
    fitted_on: dict[str, Any]
    fit: dict[str, Any] = field(default_factory=dict)

    @property
    def channels(self) -> tuple[str, ...]:
        """The channels this model draws (the others are the oracle's)."""
        return PEM_CHANNELS if self.positive is not None else PEM_CHANNELS[:1]

    def channel_parameters(self, channel: str) -> PemParameters:
        """The tables of ``channel``.

        Raises:
            ConfigError: a channel the model does not draw.
        """
        require(channel in self.channels, "channel", f"this PEM models {self.channels}, not {channel!r}")
        return self.parameters if channel == "negative" else self.positive  # type: ignore[return-value]

    def to_json(self) -> str:
        data = {
            "format": PEM_FORMAT,
            "version": PEM_VERSION,
            "channels": list(self.channels),
            "fitted_on": self.fitted_on,
            "fit": self.fit,
            "parameters": self.parameters.to_dict(),
        }
        if self.positive is not None:
            data["positive_parameters"] = self.positive.to_dict()
        return json.dumps(data, indent=1, sort_keys=True) + "\n"

    def save(self, path: str | Path) -> Path:
        """Write the model's JSON file atomically."""
        return write_text_atomic(path, self.to_json())

    @classmethod
    def from_json(cls, text: str, source: str = "pem") -> PerceptionErrorModel:
        """Parse a PEM file's text (``source`` names it in errors)."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as error:
            raise ConfigError(source, f"not a PEM file (JSON: {error})") from error
        require(isinstance(data, dict) and data.get("format") == PEM_FORMAT, source, "not a PEM file")
        require(
            data.get("version") == PEM_VERSION,
            source,
            f"PEM file version {data.get('version')!r}; this package reads version {PEM_VERSION}: refit it",
        )
        channels = data.get("channels")
        require(
            channels in (list(PEM_CHANNELS[:1]), list(PEM_CHANNELS)),
            source,
            f"models channels {channels!r}; this package reads {list(PEM_CHANNELS[:1])} or "
            f"{list(PEM_CHANNELS)}",
        )
        require(
            ("positive_parameters" in data) == ("positive" in channels),
            source,
            "its 'positive_parameters' must be given exactly when it models 'positive'",
        )
        positive = data.get("positive_parameters")
        return cls(
            parameters=PemParameters.from_dict(data["parameters"]),
            positive=PemParameters.from_dict(positive) if positive is not None else None,
            fitted_on=data["fitted_on"],
            fit=data.get("fit", {}),
        )


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for k in sorted(value):
            _flatten(f"{prefix}.{k}", value[k], out)
    else:
        out[prefix] = value


def pem_settings(config: ObservationConfig, channels: Sequence[str] = PEM_CHANNELS) -> dict[str, Any]:
    """What the detector grid's ``channels`` depend on, flat by dotted name (JSON values): the
    observation settings (``observation.*``), paper N's detector config (``detector.*``), the rig's
    paper N sensors (``rig.*``) and, for ``positive``, paper T's (``paper_t.*``, the LUX's mount in
    ``rig.lux``). A PEM is valid for these settings only."""
    from negobs_gym.detector import FusionConfig, NegativeDetectorConfig, TraversableConfig
    from negobs_gym.envs.perception import LUX_NAME, env_rig

    detector = NegativeDetectorConfig(
        grid=config.grid, fusion=FusionConfig(tighten_on_match=config.tighten_pairs)
    )
    observation = {
        "rig": config.rig,
        "sensor_noise": config.sensor_noise,
        "scan_every": config.scan_every,
        "scan_far_from_m": config.scan_far_from_m,
        "grid": dataclasses.asdict(config.grid),
    }
    rig = {
        m.name: {
            "model": dataclasses.asdict(m.model),
            "rotation": m.rotation,
            "translation_m": m.translation_m,
        }
        for m in env_rig(config.rig, config.lux_forward_m).mounts
        if m.name != LUX_NAME or "positive" in channels
    }
    tree = {"observation": observation, "detector": dataclasses.asdict(detector), "rig": rig}
    if "positive" in channels:  # what DetectorGrid builds paper T's detector with
        observation["positive_detector"] = config.positive_detector
        observation["positive_hold_s"] = config.positive_hold_s
        observation["lux_forward_m"] = config.lux_forward_m
        tree["paper_t"] = dataclasses.asdict(
            TraversableConfig(obstacle_hold_s=config.positive_hold_s, kalman_ego_motion=config.lux_ego_motion)
        )
    out: dict[str, Any] = {}
    _flatten("", json.loads(json.dumps(tree, default=repr)), out)
    return {k[1:]: v for k, v in out.items()}


def settings_mismatch(
    fitted_on: dict[str, Any], config: ObservationConfig, channels: Sequence[str] = PEM_CHANNELS
) -> list[str]:
    """The settings of ``config`` that differ from those a PEM of ``channels`` was fitted on, as texts."""
    return settings_diff(fitted_on, pem_settings(config, channels))


def settings_diff(fitted_on: dict[str, Any], now: dict[str, Any]) -> list[str]:
    """The flat settings (:func:`pem_settings`) that differ between ``fitted_on`` and ``now``, as
    texts naming both values."""
    keys = sorted(set(fitted_on) | set(now))
    return [
        f"{k} (fitted on {fitted_on.get(k, '<absent>')!r}, now {now.get(k, '<absent>')!r})"
        for k in keys
        if fitted_on.get(k, "<absent>") != now.get(k, "<absent>")
    ]


def shipped_pem_path(config: ObservationConfig) -> Path:
    """The shipped PEM for ``config``'s ``positive`` channel (:data:`SHIPPED_PEM_PATHS`)."""
    return SHIPPED_PEM_PATHS[config.positive_detector]


def load_pem(path: str | Path | None, config: ObservationConfig) -> PerceptionErrorModel:
    """The PEM in ``path`` (None: the shipped one for ``config``, :func:`shipped_pem_path`), checked
    against ``config``.

    Raises:
        ConfigError: a missing or bad file, or settings that differ from those it was fitted on
            (field ``observation.pem_model``, each difference named).
    """
    file = Path(path) if path is not None else shipped_pem_path(config)
    if not file.is_file():
        raise ConfigError("observation.pem_model", f"no PEM file {str(file)!r} (fit one: negobs pem fit)")
    model = PerceptionErrorModel.from_json(file.read_text(encoding="utf-8"), f"observation.pem_model {file}")
    diff = settings_mismatch(model.fitted_on, config, model.channels)
    if diff:
        shown = "; ".join(diff[:6]) + (f"; and {len(diff) - 6} more" if len(diff) > 6 else "")
        raise ConfigError(
            "observation.pem_model",
            f"{file} was fitted on other detector settings: {shown}. Refit it (negobs pem fit) for these",
        )
    return model


def centreline_tree(terrain: Terrain) -> cKDTree:
    """KD-tree of the track's centre line resampled every 10 cm (lateral distance to within 5 cm)."""
    line = np.asarray(terrain.track.centreline_xy_m, dtype=np.float64)
    stations = polyline_stations(line)
    s = np.arange(0.0, stations[-1] + _TRACK_SPACING_M, _TRACK_SPACING_M)
    return cKDTree(np.column_stack([np.interp(s, stations, line[:, 0]), np.interp(s, stations, line[:, 1])]))


def clutter_distance_m(
    world_xy: np.ndarray, obstacles: Sequence[PositiveObstacle], reach_m: float
) -> np.ndarray:
    """Distance of world points (N, 2) from the nearest footprint of ``obstacles`` [m] (0 inside
    one); ``inf`` farther than ``reach_m`` from all."""
    return outline_distance_m(world_xy, [o.footprint_xy_m for o in obstacles], reach_m)


def outline_distance_m(world_xy: np.ndarray, outlines: Sequence[Any], reach_m: float) -> np.ndarray:
    """Distance of world points (N, 2) from the nearest of the polygons ``outlines`` [m] (0 inside
    one); ``inf`` farther than ``reach_m`` from all."""
    out = np.full(len(world_xy), np.inf)
    for outline in outlines:
        poly = np.asarray(outline, dtype=np.float64)
        lo, hi = poly.min(axis=0) - reach_m, poly.max(axis=0) + reach_m
        near = np.flatnonzero(np.all((world_xy >= lo) & (world_xy <= hi), axis=1))
        if near.size == 0:
            continue
        pts = world_xy[near]
        start, edge = poly, np.roll(poly, -1, axis=0) - poly  # (V, 2) each
        t = np.clip(
            np.einsum("nvk,vk->nv", pts[:, None, :] - start[None], edge) / np.sum(edge**2, axis=1), 0.0, 1.0
        )
        gap = pts[:, None, :] - (start[None] + t[..., None] * edge[None])
        dist = np.sqrt(np.min(np.sum(gap**2, axis=-1), axis=1))
        dist[points_in_polygon(pts, poly)] = 0.0
        dist[dist > reach_m] = np.inf
        out[near] = np.minimum(out[near], dist)
    return out


def ground_relief_m(world_xy: np.ndarray, terrain: Terrain, window_m: float = RELIEF_WINDOW_M) -> np.ndarray:
    """Highest minus lowest heightfield sample within the ``window_m`` square around each world
    point (N, 2) [m] (the nearest sample's window; the heightfield's edge sample outside it)."""
    field = terrain.heightfield
    size = max(1, 2 * round(0.5 * window_m / field.resolution_m) + 1)
    heights = np.asarray(field.heights_m, dtype=np.float64)
    relief = ndimage.maximum_filter(heights, size=size) - ndimage.minimum_filter(heights, size=size)
    ny, nx = heights.shape
    ix = np.clip(
        np.rint((world_xy[:, 0] - field.origin_m[0]) / field.resolution_m).astype(np.int64), 0, nx - 1
    )
    iy = np.clip(
        np.rint((world_xy[:, 1] - field.origin_m[1]) / field.resolution_m).astype(np.int64), 0, ny - 1
    )
    return relief[iy, ix]


def terrain_classes(
    world_xy: np.ndarray,
    terrain: Terrain,
    tree: cKDTree,
    band_m: float,
    clutter_band_m: float,
    rough_relief_m: float,
) -> np.ndarray:
    """Index into :data:`TERRAIN_CLASSES` of world points (N, 2) (see there); ``tree`` is the
    terrain's :func:`centreline_tree`."""
    half = 0.5 * terrain.track.width_m
    lateral, index = tree.query(world_xy)
    samples = tree.data
    ahead = samples[np.minimum(index + 1, len(samples) - 1)] - samples[np.maximum(index - 1, 0)]
    right = np.sum((world_xy - samples[index]) * np.column_stack([ahead[:, 1], -ahead[:, 0]]), axis=1) > 0
    rough = ground_relief_m(world_xy, terrain) >= rough_relief_m
    plain = np.where(rough, TERRAIN_CLASSES.index("rough"), TERRAIN_CLASSES.index("smooth"))
    left_kind, right_kind = (
        plain if k == "verge" else np.full(len(world_xy), TERRAIN_CLASSES.index(k))
        for k in terrain.track.border_kinds
    )
    border = np.where(
        lateral <= half + band_m, TERRAIN_CLASSES.index("verge"), np.where(right, right_kind, left_kind)
    )
    bodies = [o for o in terrain.positive_obstacles if not o.in_heightfield]
    relief = [o for o in terrain.positive_obstacles if o.in_heightfield]
    to_body = clutter_distance_m(world_xy, bodies, clutter_band_m)
    to_relief = clutter_distance_m(world_xy, relief, clutter_band_m)
    nearest = np.where(to_body <= to_relief, TERRAIN_CLASSES.index("clutter"), TERRAIN_CLASSES.index("mound"))
    classes = np.where(np.isfinite(np.minimum(to_body, to_relief)), nearest, border)
    return np.where(lateral <= half, TERRAIN_CLASSES.index("track"), classes).astype(np.int64)


@dataclass(frozen=True, eq=False)
class ClassRaster:
    """The terrain classes of a terrain's heightfield on a world raster of ``resolution_m`` cells,
    built once per terrain, so a frame looks its cells' classes up instead of measuring them (the
    fit's rows and the model use the same raster)."""

    origin_m: tuple[float, float]
    resolution_m: float
    classes: np.ndarray  # (ny, nx) uint8, index into TERRAIN_CLASSES

    @classmethod
    def build(
        cls,
        terrain: Terrain,
        tree: cKDTree,
        band_m: float,
        clutter_band_m: float,
        rough_relief_m: float,
        resolution_m: float = CLASS_RASTER_M,
    ) -> ClassRaster:
        x0, x1, y0, y1 = terrain.heightfield.extent_m
        xs = np.arange(x0, x1 + resolution_m, resolution_m)
        ys = np.arange(y0, y1 + resolution_m, resolution_m)
        xx, yy = np.meshgrid(xs + 0.5 * resolution_m, ys + 0.5 * resolution_m)
        points = np.column_stack([xx.ravel(), yy.ravel()])
        classes = terrain_classes(points, terrain, tree, band_m, clutter_band_m, rough_relief_m)
        classes = classes.astype(np.uint8)
        return cls((float(x0), float(y0)), float(resolution_m), classes.reshape(xx.shape))

    def at(self, world_xy: np.ndarray) -> np.ndarray:
        """Class index of world points (N, 2); ``smooth`` outside the raster."""
        ny, nx = self.classes.shape
        fx = (world_xy[:, 0] - self.origin_m[0]) / self.resolution_m
        fy = (world_xy[:, 1] - self.origin_m[1]) / self.resolution_m
        inside = (fx >= 0) & (fx < nx) & (fy >= 0) & (fy < ny)  # NaN is outside
        with np.errstate(invalid="ignore"):  # truncation floors the points inside; the rest are masked
            flat = fy.astype(np.int64) * nx + fx.astype(np.int64)
        drawn = self.classes.ravel().take(flat, mode="clip").astype(np.int64)
        return np.where(inside, drawn, TERRAIN_CLASSES.index("smooth"))


def class_raster(
    terrain: Terrain, band_m: float, clutter_band_m: float, rough_relief_m: float, cache: dict | None = None
) -> ClassRaster:
    """The terrain's :class:`ClassRaster`, kept in ``cache`` (one dict per world) when given."""
    key = ("pem_classes", band_m, clutter_band_m, rough_relief_m)
    raster = cache.get(key) if cache is not None else None
    if raster is None:
        raster = ClassRaster.build(terrain, centreline_tree(terrain), band_m, clutter_band_m, rough_relief_m)
        if cache is not None:
            cache[key] = raster
    return raster


def channel_outlines(terrain: Terrain, channel: str) -> list[np.ndarray]:
    """The world outlines of ``channel``'s true obstacles: the pits' rims (``negative``), the
    positive obstacles' footprints (``positive``, mounds included, as the oracle draws them)."""
    require(channel in PEM_CHANNELS, "channel", f"must be one of {PEM_CHANNELS}, got {channel!r}")
    if channel == "negative":
        return [np.asarray(o.outline_xy_m, dtype=np.float64) for o in terrain.negative_obstacles]
    return [np.asarray(o.footprint_xy_m, dtype=np.float64) for o in terrain.positive_obstacles]


def rasterise_outlines(
    outlines: Sequence[np.ndarray], pose: Pose, grid: GridSpec, boxes: np.ndarray
) -> list[tuple[int, np.ndarray, slice, slice]]:
    """Each world outline with cells on ``grid`` around ``pose``: (its index, its cell mask in a
    window, the window's row and column slices); ``boxes`` are the outlines' :func:`outline_boxes`.
    A cell is the outline's when its centre lies inside it."""
    x0, x1, y0, y1 = grid.extent_xy_m
    corners = np.array([[x0, y0], [x0, y1], [x1, y0], [x1, y1]])
    world = _vehicle_to_world(corners, pose)
    lo, hi = world.min(axis=0), world.max(axis=0)
    near = np.flatnonzero(
        (boxes[:, 0] <= hi[0]) & (boxes[:, 2] >= lo[0]) & (boxes[:, 1] <= hi[1]) & (boxes[:, 3] >= lo[1])
    )
    out = []
    xs = -grid.side_m + (np.arange(grid.cols) + 0.5) * grid.cell_m
    ys = -grid.back_m + (np.arange(grid.rows) + 0.5) * grid.cell_m
    for k in near.tolist():
        outline = world_to_vehicle_xy(outlines[k], (pose.x, pose.y), pose.yaw)
        rows, cols = grid.window(outline.min(axis=0), outline.max(axis=0))
        if rows.start >= rows.stop or cols.start >= cols.stop:
            continue
        mask = lattice_in_polygon(xs[cols], ys[rows], outline)
        if mask.any():
            out.append((k, mask, rows, cols))
    return out


def pit_centre_distance_m(grid: GridSpec, mask: np.ndarray, rows: slice, cols: slice) -> float:
    """Distance from the vehicle origin to the mean centre of a pit's cells (paper N §4.2)."""
    r, c = np.nonzero(mask)
    x = -grid.side_m + (c.mean() + cols.start + 0.5) * grid.cell_m
    y = -grid.back_m + (r.mean() + rows.start + 0.5) * grid.cell_m
    return float(math.hypot(x, y))


def _vehicle_to_world(points: np.ndarray, pose: Pose) -> np.ndarray:
    return vehicle_to_world_xy(points, (pose.x, pose.y), pose.yaw)


def outline_boxes(outlines: Sequence[np.ndarray]) -> np.ndarray:
    """(M, 4) world bounding boxes (xmin, ymin, xmax, ymax) of ``outlines``."""
    if not outlines:
        return np.zeros((0, 4))
    return np.array([[*o.min(axis=0), *o.max(axis=0)] for o in outlines])


def _polygon_area(xy: np.ndarray) -> float:
    """Area of a simple polygon (N, 2) [m²] (the shoelace formula)."""
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def bin_index(value: float | np.ndarray, edges: np.ndarray) -> Any:
    """Bin index of ``value``: below the first edge -> 0, beyond the last -> the last bin."""
    # np.digitize's bins for rising edges, without its and np.clip's checks (a few per frame)
    return np.minimum(np.maximum(np.searchsorted(edges, value, side="right") - 1, 0), len(edges) - 2)


class PemGrid:
    """The PEM's layer of one channel (``negative`` or ``positive``) around the vehicle, frame by
    frame (one episode).

    ``rng`` is the PEM's own generator (a child of the sensors'); the same generator state, terrain
    and poses give the same layers bit for bit.
    """

    def __init__(
        self,
        model: PerceptionErrorModel,
        grid: GridSpec,
        terrain: Terrain,
        rng: np.random.Generator,
        cache: dict | None = None,
        channel: str = "negative",
    ) -> None:
        """``cache`` (one dict per world) keeps the terrain's class raster for the next episode.

        Raises:
            ConfigError: a channel the model does not draw.
        """
        p = model.channel_parameters(channel)
        self.model = model
        self.channel = channel
        self.grid = grid
        self.terrain = terrain
        self._rng = rng
        self._d_edges = np.asarray(p.distance_edges_m, dtype=np.float64)
        self._s_edges = np.asarray(p.size_edges_cells, dtype=np.float64)
        self._chain = np.stack(
            [np.asarray(getattr(p, n), dtype=np.float64) for n in _STATE_NAMES]
        )  # (2, S, D)
        self._levels = np.asarray(p.quantile_levels, dtype=np.float64)
        self._confirm = np.asarray(p.confirm_distance_m, dtype=np.float64)
        self._latency = np.asarray(p.confirm_latency_frames, dtype=np.float64)
        self._approach_m = float(p.approach_m)
        self._loss = np.asarray(p.loss_distance_m, dtype=np.float64)
        self._match_cells = int(p.match_cells)
        ns = len(p.size_edges_cells) - 1
        self._near, self._far = (
            np.broadcast_to(t, (ns, *t.shape[-2:]))
            for t in (
                np.asarray(p.near_offset_m, dtype=np.float64),
                np.asarray(p.far_offset_m, dtype=np.float64),
            )
        )
        keep = np.asarray(p.fa_keep, dtype=np.float64)
        self._fa_keep = keep
        density = np.asarray(p.fa_density_per_m2, dtype=np.float64)
        self._fa_density = density
        self._blobs = np.asarray(p.fa_blobs, dtype=np.float64).reshape(-1, 6)
        centres = grid.cell_centres()
        self._centres = centres  # vehicle frame (rows, cols, 2)
        b = _BLOCK_CELLS
        rows, cols = grid.rows // b * b, grid.cols // b * b
        blocks = centres[:rows, :cols].reshape(rows // b, b, cols // b, b, 2).mean(axis=(1, 3))
        self._block_centres = blocks.reshape(-1, 2)
        self._block_m = b * grid.cell_m
        self._block_bins = bin_index(np.hypot(*self._block_centres.T), self._d_edges)
        self._outlines = channel_outlines(terrain, channel)
        self._boxes = outline_boxes(self._outlines)
        # rounded: a 1 x 1 m box's 24.999999999999996 cells must size it as the fit's 25 rasterised ones
        self._rim_cells = np.round([_polygon_area(o) / grid.cell_m**2 for o in self._outlines], 6)
        self._tree = centreline_tree(terrain)
        self._classes = class_raster(terrain, p.border_band_m, p.clutter_band_m, p.rough_relief_m, cache)
        n = len(self._outlines)
        self._state = np.zeros(n, dtype=np.int8)
        self._seen = np.zeros(n, dtype=np.int64)  # frames each pit was on the grid before its first drawing
        self._confirm_at = np.full(n, np.nan)  # each pit's drawn first-confirmation distance ...
        self._latency_at = np.zeros(n)  # ... or latency (first seen within reach) ...
        self._lost_at = np.zeros(n)  # ... and loss distance, drawn at its first sighting
        self._near_first = np.zeros(n, dtype=bool)  # first seen within ``approach_m``
        # the world point each pit was first drawn from (paper N's fusion keeps a pit's cells in
        # the world); the positive channel's obstacles are drawn from where the car is
        self._view_xy = np.full((n, 2), np.nan)
        self._fa_xy = np.zeros((0, 2))  # world centres of the live false alarms
        self._fa_blob = np.zeros(0, dtype=np.int64)  # the library blob each copies
        self._fa_class = np.zeros(0, dtype=np.int64)  # the terrain class each was born on
        self._last_pose: Pose | None = None  # the pose of the frame before (which ground was in view)

    def layer(self, pose: Pose) -> np.ndarray:
        """This frame's layer of the channel (rows, cols) bool around the true ``pose``."""
        layer = np.zeros(self.grid.shape, dtype=bool)
        truths = rasterise_outlines(self._outlines, pose, self.grid, self._boxes)
        channel_is_positive = self.channel == "positive"
        for k, mask, rows, cols in truths:
            cells = int(mask.sum())
            centre = pit_centre_distance_m(self.grid, mask, rows, cols)
            s, d = int(bin_index(cells, self._s_edges)), int(bin_index(centre, self._d_edges))
            if np.isnan(self._confirm_at[k]):
                self._first_sighting(k, centre)
            if centre < self._lost_at[k] and (self._state[k] != NEVER or self._near_first[k]):
                self._state[k] = GONE
            if self._state[k] == GONE:
                continue
            if self._state[k] == NEVER:
                self._seen[k] += 1
                drawn = centre <= self._confirm_at[k]
                if self._near_first[k]:
                    drawn = drawn and self._seen[k] > self._latency_at[k]
            else:
                drawn = bool(self._rng.random() < self._chain[self._state[k] - 1, s, d])
            self._state[k] = DRAWN if drawn else (NEVER if self._state[k] == NEVER else LOST)
            if drawn:
                if np.isnan(self._view_xy[k, 0]) or channel_is_positive:
                    self._view_xy[k] = (pose.x, pose.y)
                self._draw_pit(layer, mask, rows, cols, s, d, pose, self._view_xy[k])
        self._false_alarms(layer, pose, truths)
        return layer

    def _first_sighting(self, k: int, centre: float) -> None:
        """Draw obstacle ``k``'s first confirmation distance (-1: never drawn), its latency when it
        is first seen within ``approach_m`` (an episode's cold start: it is drawn once within its
        distance and seen that long), and its loss distance. The loss holds once the obstacle was
        drawn (one confirmed nearer than its loss is drawn in that frame only: the detector's late
        confirmations are lost within a frame or two), and for one first seen within
        ``approach_m`` from the start (one already nearer than its loss is never drawn: the LUX's
        layers pass over it)."""
        whole = int(bin_index(self._rim_cells[k], self._s_edges))  # its size, not the part in view
        self._confirm_at[k] = self._confirm_distance(self._confirm[whole])
        self._near_first[k] = centre < self._approach_m
        if self._near_first[k]:
            self._latency_at[k] = self._quantile(self._latency)
        if self._loss.size:
            self._lost_at[k] = self._quantile(self._loss[whole])

    def _quantile(self, table: np.ndarray) -> float:
        return float(np.interp(self._rng.random(), self._levels, table))

    def _confirm_distance(self, table: np.ndarray) -> float:
        """A first-confirmation distance from its quantiles, where -1 (never) is a point mass: a
        draw between it and the nearest distance is rounded to the nearer of the two, not read as
        a distance in between (a pit first drawn at 4 m that the detector never draws so near)."""
        value = self._quantile(table)
        reached = table[table >= 0]
        if reached.size and -1.0 < value < reached[0]:
            value = -1.0 if value < 0.5 * (reached[0] - 1.0) else float(reached[0])
        return value

    def _draw_pit(
        self,
        layer: np.ndarray,
        mask: np.ndarray,
        rows: slice,
        cols: slice,
        s: int,
        d: int,
        pose: Pose,
        view_xy: np.ndarray,
    ) -> None:
        """The drawn cells of a pit: its rim's cells (grown where the far offset says) in its bearing
        span, between its near edge + the near offset and its far edge + the far offset.

        Range and bearing are measured from ``view_xy``: for a pit the world point it was first
        drawn from, not where the car is now (paper N's fusion keeps a pit's cells in the world,
        so its outline errors lie along the view it was found from); for the ``positive``
        channel's obstacles the car's place, as paper T's LUX draws the face it sees. Measured
        from the car's place, a pit beside it grew sideways towards the car by the near offset
        (its inner side 0.26 m nearer than the rim on average, the detector's 0.08 m;
        docs/notebook/pem.md, "Close passes on OffroadNav-v2")."""
        near, far = self._quantile(self._near[s, d]), self._quantile(self._far[s, d])
        grow = min(_MAX_GROW_CELLS, math.ceil(max(0.0, -near, far) / self.grid.cell_m))
        r0, r1 = max(rows.start - grow, 0), min(rows.stop + grow, self.grid.rows)
        c0, c1 = max(cols.start - grow, 0), min(cols.stop + grow, self.grid.cols)
        truth = np.zeros((r1 - r0, c1 - c0), dtype=bool)
        truth[rows.start - r0 : rows.stop - r0, cols.start - c0 : cols.stop - c0] = mask
        window = self._centres[r0:r1, c0:c1]
        rel_xy = _vehicle_to_world(window.reshape(-1, 2), pose).reshape(window.shape) - view_xy
        rng_m = np.hypot(rel_xy[..., 0], rel_xy[..., 1])
        bearing = np.arctan2(rel_xy[..., 0], rel_xy[..., 1])
        centre_bearing = float(np.arctan2(np.sin(bearing[truth]).mean(), np.cos(bearing[truth]).mean()))
        rel = np.angle(np.exp(1j * (bearing - centre_bearing)))
        slack = 0.5 * self.grid.cell_m / np.maximum(rng_m, self.grid.cell_m)
        lo, hi = rng_m[truth].min() + near, rng_m[truth].max() + far
        region = ndimage.binary_dilation(truth, iterations=grow) if grow > 0 else truth
        span = (rel >= rel[truth].min() - slack) & (rel <= rel[truth].max() + slack)
        reach = region & span
        # the near edge is the cell range nearest the drawn one (the fit measured the detector's
        # between cell centres): cutting at ``lo`` drew no cell in front for an offset in (-1, 0) cells
        candidates = rng_m[reach]
        lo = float(candidates[np.argmin(np.abs(candidates - lo))]) if candidates.size else lo
        drawn = reach & (rng_m >= lo) & (rng_m <= max(hi, lo))
        # a drawn pit is one blob on its rim, as the detector's hits: the range band beside the car
        # can leave slivers of the grown rim, or nothing on it
        labels, count = ndimage.label(drawn, structure=_EIGHT)
        on_rim = np.unique(labels[truth & drawn])
        if on_rim.size == 0:  # the rim's cell nearest the drawn near edge
            candidates = np.where(truth, np.abs(rng_m - lo), np.inf)
            drawn = candidates == candidates.min()
        elif count > 1:
            drawn = np.isin(labels, on_rim)
        layer[r0:r1, c0:c1] |= drawn

    def _pick_blobs(self, classes: np.ndarray, bins: np.ndarray) -> np.ndarray:
        """A library blob for each new false alarm: one of its class and distance bin, else of its
        class, else of its fallback class (:data:`FALLBACK_CLASS`), else any."""
        lib_class, lib_bin = self._blobs[:, 0].astype(np.int64), self._blobs[:, 1].astype(np.int64)
        picks = np.empty(len(classes), dtype=np.int64)
        for i, (c, d) in enumerate(zip(classes.tolist(), bins.tolist(), strict=True)):
            pool = np.flatnonzero((lib_class == c) & (lib_bin == d))
            if pool.size == 0:
                pool = np.flatnonzero(lib_class == c)
            for other in fallback_chain(TERRAIN_CLASSES[c]):
                if pool.size == 0:
                    pool = np.flatnonzero(lib_class == TERRAIN_CLASSES.index(other))
            if pool.size == 0:
                pool = np.arange(len(self._blobs))
            picks[i] = pool[int(self._rng.integers(pool.size))]
        return picks

    def _place(self, world_xy: np.ndarray, edge_m: np.ndarray) -> np.ndarray:
        """Each point moved across the track to ``edge_m`` beyond the nearer edge (its side kept)."""
        _, index = self._tree.query(world_xy)
        samples = self._tree.data
        ahead = samples[np.minimum(index + 1, len(samples) - 1)] - samples[np.maximum(index - 1, 0)]
        tangent = ahead / np.maximum(np.linalg.norm(ahead, axis=1, keepdims=True), 1e-9)
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
        offset = world_xy - samples[index]
        side = np.where(np.sum(offset * normal, axis=1) >= 0, 1.0, -1.0)
        along = np.sum(offset * tangent, axis=1)
        lateral = side * (0.5 * self.terrain.track.width_m + edge_m)
        return samples[index] + along[:, None] * tangent + lateral[:, None] * normal

    def _false_alarms(self, layer: np.ndarray, pose: Pose, truths: list) -> None:
        """Keep, age and add the world-fixed false alarms; draw those on the grid into ``layer``.
        They keep clear of ``truths`` (this frame's rasterised true obstacles) by the fit's
        ``match_cells``: a new one is moved to a block of its class and distance bin until it is
        (the fit divided the class's alarms by all its area, the obstacles' cells included), a live
        one that the grid's rounding brings nearer is not drawn that frame."""
        blocks_world = _vehicle_to_world(self._block_centres, pose)
        # a block's class is read at one point of it, the same random one in all blocks each frame:
        # read at their centres, a lattice that keeps its place across a straight track reads a band
        # narrower than two blocks by whole blocks (the 1 m verge band 19 % short, docs/pem.md)
        probe = (self._rng.random(2) - 0.5) * self._block_m
        classes = self._classes.at(blocks_world + vehicle_to_world_xy(probe, (0.0, 0.0), pose.yaw))
        if len(self._fa_xy):  # the live ones: kept with their class's and bin's probability on the grid
            local = world_to_vehicle_xy(self._fa_xy, (pose.x, pose.y), pose.yaw)
            inside = self.grid.contains(local)
            bins = bin_index(np.hypot(local[:, 0], local[:, 1]), self._d_edges)
            keep = inside & (self._rng.random(len(self._fa_xy)) < self._fa_keep[self._fa_class, bins])
            self._fa_xy, self._fa_blob, self._fa_class = (
                self._fa_xy[keep],
                self._fa_blob[keep],
                self._fa_class[keep],
            )
        # births bring each block's ground to its class's and bin's mean: that mean less what
        # survives of the mean where the ground was the frame before (the farther bin as the car
        # advances; none for ground that comes into view, all of the mean in the first frame)
        mean = self._fa_density[classes, self._block_bins]
        inflow = np.zeros(len(classes))
        if self._last_pose is not None:
            before = world_to_vehicle_xy(
                blocks_world, (self._last_pose.x, self._last_pose.y), self._last_pose.yaw
            )
            seen = self.grid.contains(before)
            was = bin_index(np.hypot(before[:, 0], before[:, 1]), self._d_edges)
            inflow = np.where(seen, self._fa_density[classes, was], 0.0)
        self._last_pose = pose
        rate = np.maximum(mean - self._fa_keep[classes, self._block_bins] * inflow, 0.0)
        counts = self._rng.poisson(rate * self._block_m**2)
        forbidden = None  # built only when an alarm is to be placed or drawn near a true obstacle
        if truths and ((counts.any() and len(self._blobs)) or len(self._fa_xy)):
            forbidden = self._forbidden(truths)
        if counts.any() and len(self._blobs):
            at = np.repeat(np.arange(len(counts)), counts)
            picks = self._pick_blobs(classes[at], self._block_bins[at])
            born = self._born(at, picks, classes[at], pose)
            clear = np.ones(len(at), dtype=bool)
            if forbidden is not None:
                clear = self._clear(born, picks, pose, forbidden)
                for _ in range(_PLACE_TRIES):
                    if clear.all():
                        break
                    again = np.flatnonzero(~clear)
                    at[again] = self._same_kind_block(at[again], classes)
                    born[again] = self._born(at[again], picks[again], classes[at[again]], pose)
                    clear[again] = self._clear(born[again], picks[again], pose, forbidden)
            self._fa_xy = np.concatenate([self._fa_xy, born[clear]])
            self._fa_blob = np.concatenate([self._fa_blob, picks[clear]])
            self._fa_class = np.concatenate([self._fa_class, classes[at][clear]])
        if len(self._fa_xy):
            local = world_to_vehicle_xy(self._fa_xy, (pose.x, pose.y), pose.yaw)
            rows, cols, _ = self.grid.cell_of(local)
            for row, col, blob in zip(rows.tolist(), cols.tolist(), self._fa_blob.tolist(), strict=True):
                (r0, r1), (c0, c1) = self._blob_window(row, col, blob)
                if forbidden is None or not forbidden[r0:r1, c0:c1].any():
                    layer[r0:r1, c0:c1] = True

    def _born(self, at: np.ndarray, picks: np.ndarray, classes: np.ndarray, pose: Pose) -> np.ndarray:
        """World centres of new false alarms in blocks ``at`` (uniform in the block; the track-bound
        classes moved across the track to their blob's distance from the edge)."""
        offsets = (self._rng.random((len(at), 2)) - 0.5) * self._block_m
        born = _vehicle_to_world(self._block_centres[at] + offsets, pose)
        moved = _PLACED_BY_EDGE[classes]
        if moved.any():
            born[moved] = self._place(born[moved], self._blobs[picks[moved], 2])
        return born

    def _same_kind_block(self, at: np.ndarray, classes: np.ndarray) -> np.ndarray:
        """A random block of the same terrain class and distance bin as each of blocks ``at``."""
        out = at.copy()
        for i, block in enumerate(at.tolist()):
            pool = np.flatnonzero((classes == classes[block]) & (self._block_bins == self._block_bins[block]))
            out[i] = pool[int(self._rng.integers(pool.size))]
        return out

    def _blob_window(self, row: int, col: int, blob: int) -> tuple[tuple[int, int], tuple[int, int]]:
        """The grid rows and columns a library blob centred on (row, col) covers: its box's columns
        (across the car's heading, so it reaches as far sideways as the detector's did: the LUX's
        alarms on the track are streaks across a track edge, which the judge leaves out when they
        touch its border band) and as many of its rows as its cells fill."""
        along, across, cells = (int(v) for v in self._blobs[blob, 3:])
        length = max(1, min(along, math.ceil(cells / across)))
        ra, ca = row - length // 2, col - across // 2
        return (max(ra, 0), max(ra + length, 0)), (max(ca, 0), max(ca + across, 0))

    def _forbidden(self, truths: list) -> np.ndarray:
        """The cells a false alarm must not touch: the true obstacles' grown by ``match_cells``."""
        full = np.zeros(self.grid.shape, dtype=bool)
        for _, mask, rows, cols in truths:
            full[rows, cols] |= mask
        return ndimage.binary_dilation(full, iterations=self._match_cells) if self._match_cells else full

    def _clear(self, born: np.ndarray, picks: np.ndarray, pose: Pose, forbidden: np.ndarray) -> np.ndarray:
        """Whether each new false alarm's blob keeps off ``forbidden`` (one off the grid does)."""
        local = world_to_vehicle_xy(born, (pose.x, pose.y), pose.yaw)
        rows, cols, inside = self.grid.cell_of(local)
        out = np.ones(len(born), dtype=bool)
        for i in np.flatnonzero(inside):
            (r0, r1), (c0, c1) = self._blob_window(int(rows[i]), int(cols[i]), int(picks[i]))
            out[i] = not forbidden[r0:r1, c0:c1].any()
        return out
