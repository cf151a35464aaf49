"""Fit a perception-error model (:mod:`negobs_gym.envs.pem`) from the detector's drives.

:func:`fit_pem` drives the courses of :mod:`negobs_gym.eval.pem_data` through the detector grid and
fits each channel's tables (``negative``: the pits; ``positive``: the rocks, boxes and mounds) from
its rows (:func:`fit_parameters`, from the CSVs alone, the same for both channels):

- first confirmation: quantiles (pooled over sizes for now) of the distance at which the pits that
  came onto the grid from beyond the detector's reach were first drawn (a pit passed undrawn counts as
  never), and of the frames the pits first seen within reach took to be drawn (the fusion's
  latency at an episode's start);
- for the positive channel, the loss: quantiles per size bin of the distance at which an
  obstacle passed on its approach was last drawn (the LUX's layers pass over it there);
- after the first drawing (and up to the loss), per state (drawn the frame before, drawn
  earlier), size bin and 2 m distance bin,
  the share of sightings drawn, shrunk toward the distance bin's share over all sizes by
  :data:`PRIOR_SIGHTINGS` pseudo-sightings (that toward the bin's recall over all states, that
  toward the state's share), so a bin seen a few times keeps its neighbours' value;
- the near- and far-edge offsets: quantiles per distance bin of the drawn sightings (all of a
  bin's sightings pooled over sizes; a bin with fewer than :data:`MIN_OFFSETS` takes all bins');
- false alarms: spurious blobs per frame per m² of each terrain class (track, verge, bank,
  drop-off, smooth and rough ground, clutter, mound) and distance bin, a bin's rate shrunk toward
  its class's by :data:`PRIOR_AREA_M2` of pseudo-area; the share of them seen the frame before
  (their persistence, per class and distance bin: paper T's LUX keeps none within 8 m), and up to
  :data:`MAX_BLOBS` of them (their distance from the track edge, box and cells) for new ones to
  copy. A class the drives never showed takes the rates of the first class of its
  :func:`~negobs_gym.envs.pem.fallback_chain` they did (its ``fa_area_m2`` stays 0).

Then, for ``calibration_passes`` passes (:func:`calibrate`), the model drives the fit's own courses
and its recall is brought to the detector's there (the method of simulated moments): each 2 m
distance bin's chain shares are scaled by the detector's recall over the PEM's. The tables alone
do not give the recall back: the chain is fitted between each obstacle's first and last drawing,
where a miss always ends in a return, and its draws are independent of the loss distance's (on the
fit's own courses the uncalibrated positive channel drew 6 points too many at 6-10 m).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.envs.pem import (
    TERRAIN_CLASSES,
    PemParameters,
    PerceptionErrorModel,
    bin_index,
    fallback_chain,
    pem_settings,
    settings_diff,
)
from negobs_gym.errors import ConfigError
from negobs_gym.eval.campaign import RunOptions, read_csv
from negobs_gym.eval.pem_data import (
    CHANNEL_TABLES,
    DISTANCE_EDGES_M,
    MODES,
    PemCampaignConfig,
    run_pem_campaign,
)

__all__ = [
    "CALIBRATION_MIN_COUNT",
    "MIN_OFFSETS",
    "PRIOR_SIGHTINGS",
    "QUANTILE_LEVELS",
    "SIZE_EDGES_CELLS",
    "calibrate",
    "calibration_factors",
    "fit_parameters",
    "fit_pem",
]

#: Size bins of a pit's rim cells: below paper N Table 7's smallest, its rows paired, above its largest.
SIZE_EDGES_CELLS: tuple[float, ...] = (0.0, 15.0, 25.0, 35.0, 45.0, 56.0, 10_000.0)
#: Levels of every quantile table: 5 % steps, finer in the tails, where a first confirmation's
#: "never" (-1) is a point mass of ~0.5 % that a draw between two levels must not spread over 5 %.
QUANTILE_LEVELS: tuple[float, ...] = tuple(
    float(q)
    for q in np.concatenate(
        [
            [0.0, 0.0025, 0.005, 0.01, 0.02, 0.03],
            np.linspace(0.05, 0.95, 19),
            [0.97, 0.98, 0.99, 0.995, 0.9975, 1.0],
        ]
    )
)
#: Pseudo-sightings a chain entry is shrunk toward its distance bin's share by (not a paper value).
PRIOR_SIGHTINGS = 4.0
#: Fewest drawn sightings a distance bin's offset quantiles are taken from, else all bins'.
MIN_OFFSETS = 20
#: A pit first seen at least this far (its centre) came from beyond paper N's 20 m reach: its first
#: drawing is a first-confirmation distance [m].
APPROACH_M = 22.0
#: A pit last seen this near was passed (an undrawn one was missed, not cut off by the course's end) [m].
PASSED_M = 6.0
#: Fewest first confirmations a size bin's own quantiles are taken from (with ``confirm_by_size``),
#: else the pooled ones.
MIN_CONFIRMATIONS = 10
#: Most false-alarm blobs the model keeps to copy.
MAX_BLOBS = 400
#: Largest fitted false-alarm persistence (a blob kept forever would never leave the model).
MAX_FA_KEEP = 0.98
#: Pseudo-area (m² x frames) a class's rate in one distance bin is shrunk toward the class's rate
#: over all distances by (not a paper value: ~10 frames of a 2 m bin's verge band).
PRIOR_AREA_M2 = 50.0
#: Fewest sightings of a distance bin (each grid's) a calibration factor is taken from, else 1 (the
#: check's floor for a recall bin).
CALIBRATION_MIN_COUNT = 30


def _float(text: str) -> float:
    return float(text)


def _pits(rows: list[dict[str, str]]) -> dict[tuple[str, str], list[dict[str, str]]]:
    """Each pit's sightings (by course and obstacle), in frame order."""
    out: dict[tuple[str, str], list[dict[str, str]]] = {}
    for r in sorted(rows, key=lambda r: (r["episode"], int(r["obstacle"]), int(r["frame"]))):
        out.setdefault((r["episode"], r["obstacle"]), []).append(r)
    return out


def _approach(rows: list[dict[str, str]]) -> int:
    """Index of an obstacle's nearest sighting: the frames up to it are its approach."""
    return int(np.argmin([float(r["centre_m"]) for r in rows]))


def _last_drawn(rows: list[dict[str, str]]) -> int | None:
    """Index of an obstacle's last drawing on its approach (None: never drawn on it)."""
    hits = [i for i, r in enumerate(rows[: _approach(rows) + 1]) if r["detected"] == "1"]
    return hits[-1] if hits else None


def _chain(
    pits: dict, s_edges: np.ndarray, d_edges: np.ndarray, until_lost: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(2, S, D) drawn and seen counts after a pit's first drawing, by state (drawn the frame
    before, drawn earlier), size and distance; and all sightings and the drawn ones per (size,
    distance). ``until_lost``: the chain's counts stop at the last drawing on the approach (the
    loss distance models what follows)."""
    ns, nd = len(s_edges) - 1, len(d_edges) - 1
    seen, drawn, every = np.zeros((2, ns, nd)), np.zeros((2, ns, nd)), np.zeros((ns, nd))
    every_drawn = np.zeros((ns, nd))
    for rows in pits.values():
        state = None  # before the first drawing
        last = _last_drawn(rows) if until_lost else len(rows) - 1
        for i, r in enumerate(rows):
            s = int(bin_index(float(r["cells"]), s_edges))
            d = int(bin_index(float(r["centre_m"]), d_edges))
            hit = r["detected"] == "1"
            every[s, d] += 1
            every_drawn[s, d] += hit
            if last is None or i > last:
                continue
            if state is not None:
                seen[state, s, d] += 1
                drawn[state, s, d] += hit
            if hit:
                state = 0
            elif state is not None:
                state = 1
    return seen, drawn, every, every_drawn


def _losses(pits: dict, s_edges: np.ndarray) -> list[list[float]]:
    """Per size bin (a pit's most cells on the grid), the loss distances of the obstacles that
    came from beyond :data:`APPROACH_M`, were drawn on their approach and passed within
    :data:`PASSED_M`: the midpoint of the centre distances of the last drawing and the frame after."""
    ns = len(s_edges) - 1
    out: list[list[float]] = [[] for _ in range(ns)]
    for rows in pits.values():
        centre = [float(r["centre_m"]) for r in rows]
        nearest, last = _approach(rows), _last_drawn(rows)
        if centre[0] < APPROACH_M or centre[nearest] > PASSED_M or last is None:
            continue
        cells = max(int(r["cells"]) for r in rows)
        s = int(bin_index(cells, s_edges))
        out[s].append(0.5 * (centre[last] + centre[min(last + 1, nearest)]))
    return out


def _confirmations(pits: dict, s_edges: np.ndarray) -> tuple[list[list[float]], list[float]]:
    """Per size bin (a pit's most cells on the grid), the first-drawing distances of the pits that
    came from beyond :data:`APPROACH_M` (the midpoint of the frame before and the frame drawn; -1
    for a pit passed undrawn, a pit still ahead when its course ended left out); the frames from
    first sighting to first drawing of the pits first seen nearer."""
    ns = len(s_edges) - 1
    distances: list[list[float]] = [[] for _ in range(ns)]
    latencies: list[float] = []
    for rows in pits.values():
        centre = [float(r["centre_m"]) for r in rows]
        hits = [i for i, r in enumerate(rows) if r["detected"] == "1"]
        cells = max(int(r["cells"]) for r in rows)  # the whole rim's, as the PEM sizes a pit
        s = int(bin_index(cells, s_edges))
        if centre[0] >= APPROACH_M:
            if hits:
                i = hits[0]
                distances[s].append(0.5 * (centre[i] + centre[max(i - 1, 0)]))
            elif centre[-1] <= PASSED_M:
                distances[s].append(-1.0)
        elif hits:
            latencies.append(float(int(rows[hits[0]]["frame"]) - int(rows[0]["frame"])))
    return distances, latencies


def _shrunk(seen: np.ndarray, drawn: np.ndarray, every: np.ndarray, every_drawn: np.ndarray) -> np.ndarray:
    """Each state's share drawn per (size, distance), shrunk toward the distance bin's, that toward
    the bin's share over all sightings (every state), that toward the state's overall share, that
    toward 1/2. The middle step keeps a bin the chain rarely reaches at what the detector does
    there: near the car, where the LUX sees nothing, a rock drawn at 4.1 m is not kept at 3.9 m."""
    overall = (drawn.sum(axis=(1, 2)) + 1.0) / (seen.sum(axis=(1, 2)) + 2.0)  # (states,)
    recall = (every_drawn.sum(axis=0)[None, :] + PRIOR_SIGHTINGS * overall[:, None]) / (
        every.sum(axis=0)[None, :] + PRIOR_SIGHTINGS
    )  # (states, D)
    by_distance = (drawn.sum(axis=1) + PRIOR_SIGHTINGS * recall) / (
        seen.sum(axis=1) + PRIOR_SIGHTINGS
    )  # (states, D)
    return (drawn + PRIOR_SIGHTINGS * by_distance[:, None, :]) / (seen + PRIOR_SIGHTINGS)


def _quantiles(values: np.ndarray, levels: np.ndarray) -> list[float]:
    return [float(v) for v in np.quantile(values, levels)] if values.size else [0.0] * len(levels)


def _offsets(
    sightings: list[dict], s_edges: np.ndarray, d_edges: np.ndarray, levels: np.ndarray
) -> tuple[list[list[list[float]]], list[list[list[float]]]]:
    """Quantiles of the drawn near- and far-edge offsets per size bin (the cells in view, as the
    chain's) and distance bin: a bin with fewer than :data:`MIN_OFFSETS` hits takes its size's
    over all distances, then its distance's over all sizes, then all. The size matters most: the
    structure channel draws a rock or box a cell before its face and a mound's far side only."""
    hits = [r for r in sightings if r["detected"] == "1"]
    d_hit = bin_index(np.array([float(r["centre_m"]) for r in hits]), d_edges)
    s_hit = bin_index(np.array([float(r["cells"]) for r in hits]), s_edges)
    near_all = np.array([_float(r["near_offset_m"]) for r in hits])
    far_all = np.array([_float(r["far_offset_m"]) for r in hits])

    def pool(s: int, d: int) -> np.ndarray:
        pools = ((s_hit == s) & (d_hit == d), s_hit == s, d_hit == d, np.ones(len(hits), dtype=bool))
        return next(p for p in pools if p.sum() >= MIN_OFFSETS or p.all())

    bins = [[pool(s, d) for d in range(len(d_edges) - 1)] for s in range(len(s_edges) - 1)]
    near = [[_quantiles(near_all[use], levels) for use in row] for row in bins]
    far = [[_quantiles(far_all[use], levels) for use in row] for row in bins]
    return near, far


def fit_parameters(
    sightings_csv: str | Path,
    spurious_csv: str | Path,
    frames_csv: str | Path,
    border_band_m: float,
    clutter_band_m: float,
    rough_relief_m: float,
    confirm_by_size: bool = False,
    loss_by_distance: bool = False,
    match_cells: int = 0,
    fragment_m: float = 0.0,
) -> PemParameters:
    """The PEM's tables from the detector rows of a drive (:mod:`negobs_gym.eval.pem_data`).

    ``confirm_by_size``: first-confirmation quantiles per size bin (those with at least
    :data:`MIN_CONFIRMATIONS`, else pooled): the positive obstacles, whole on the grid from far
    out, are found at distances that depend on their kind (a box's face ~12 m out, a rock's ~10 m).
    Pooled (default) for the pits, a far one shows part of its rim.

    ``loss_by_distance``: loss distances per size bin (as the first confirmations), and the chain
    fitted up to each obstacle's last drawing on its approach: the LUX loses an obstacle for good
    where its layers pass over it. ``match_cells``: the judge's (the fit's rows counted a blob
    within that many cells of an obstacle as drawing it). ``fragment_m`` > 0: the spurious blobs
    whose centre lies within that distance of a pit's rim (``pit_m``) are fragments of the pit's
    drawing and stay out of the false-alarm tables (:attr:`PemCampaignConfig.pit_fragment_m`).

    Raises:
        ConfigError: the rows hold no frame of the detector, or ``fragment_m`` > 0 and the rows
            predate ``pit_m`` (drive them again).
    """
    sightings = [r for r in read_csv(sightings_csv) if r["mode"] == "detector"]
    spurious = [r for r in read_csv(spurious_csv) if r["mode"] == "detector"]
    if fragment_m > 0 and spurious:
        if "pit_m" not in spurious[0]:
            raise ConfigError("spurious", f"{spurious_csv} has no pit_m column: drive the courses again")
        spurious = [r for r in spurious if r["pit_m"] == "" or float(r["pit_m"]) > fragment_m]
    frames = [r for r in read_csv(frames_csv) if r["mode"] == "detector"]
    if not frames:
        raise ConfigError("frames", f"{frames_csv} holds no detector frame to fit on")
    d_edges, s_edges = np.asarray(DISTANCE_EDGES_M), np.asarray(SIZE_EDGES_CELLS)
    nd, levels = len(d_edges) - 1, np.asarray(QUANTILE_LEVELS)
    pits = _pits(sightings)
    seen, drawn, every, every_drawn = _chain(pits, s_edges, d_edges, until_lost=loss_by_distance)
    p_keep, p_return = _shrunk(seen, drawn, every, every_drawn)
    by_size, latencies = _confirmations(pits, s_edges)
    # pooled over sizes: the rows hold the cells in view, and a pit far out shows part of its rim,
    # so a size bin of the rows is not the whole-rim size the model draws by (docs/pem.md)
    pooled = np.concatenate([np.asarray(v) for v in by_size])
    confirm = [
        _quantiles(np.asarray(v), levels)
        if confirm_by_size and len(v) >= MIN_CONFIRMATIONS
        else _quantiles(pooled, levels)
        for v in by_size
    ]
    latency = _quantiles(np.asarray(latencies), levels)
    loss: list[list[float]] = []
    if loss_by_distance:
        losses = _losses(pits, s_edges)
        pooled_loss = np.concatenate([np.asarray(v) for v in losses])
        loss = [
            _quantiles(np.asarray(v), levels)
            if len(v) >= MIN_CONFIRMATIONS
            else _quantiles(pooled_loss, levels)
            for v in losses
        ]

    near, far = _offsets(sightings, s_edges, d_edges, levels)

    nc = len(TERRAIN_CLASSES)
    area = np.array([[float(r[f"area_{c}_{k}"]) for c in TERRAIN_CLASSES for k in range(nd)] for r in frames])
    area = area.sum(axis=0).reshape(nc, nd)
    counts = np.zeros((nc, nd))
    klass = {c: i for i, c in enumerate(TERRAIN_CLASSES)}
    for r in spurious:
        d = int(bin_index(float(r["distance_m"]), d_edges))
        counts[klass[r["terrain_class"]], d] += 1
    class_rate = counts.sum(axis=1) / np.maximum(area.sum(axis=1), 1e-9)
    density = (counts + PRIOR_AREA_M2 * class_rate[:, None]) / (area + PRIOR_AREA_M2)
    # persistence per class and distance bin where a blob would be the next frame (its distance
    # less the car's advance): the blobs seen again there / those of the frame before headed
    # there (frames in a row only), shrunk toward the class's share by PRIOR_SIGHTINGS blobs
    travelled = {(r["episode"], int(r["frame"])): float(r["travelled_m"]) for r in frames}
    before, again = np.zeros((nc, nd)), np.zeros((nc, nd))
    for r in spurious:
        c, ahead = klass[r["terrain_class"]], travelled.get((r["episode"], int(r["frame"]) + 1))
        if ahead is not None:
            before[c, bin_index(float(r["distance_m"]) - ahead, d_edges)] += 1
        again[c, bin_index(float(r["distance_m"]), d_edges)] += r["seen_before"] == "1"
    by_class = np.where(before.sum(axis=1) > 0, again.sum(axis=1) / np.maximum(before.sum(axis=1), 1), 0.0)
    keep = (again + PRIOR_SIGHTINGS * by_class[:, None]) / (before + PRIOR_SIGHTINGS)
    keep = np.clip(keep, 0.0, MAX_FA_KEEP)
    # a kept blob moves one bin nearer as the car advances: no more may be kept into a bin than
    # its rate holds (paper T's LUX draws none within 8 m; a rare one headed there says little)
    with np.errstate(divide="ignore", invalid="ignore"):
        cap = np.where(density[:, 1:] > 0, density[:, :-1] / density[:, 1:], 1.0)
    keep[:, :-1] = np.minimum(keep[:, :-1], cap)
    for name in TERRAIN_CLASSES:  # a class never driven: the rates of the first in its chain that was
        c = klass[name]
        donors = [klass[f] for f in fallback_chain(name) if area[klass[f]].sum() > 0]
        if area[c].sum() <= 0 and donors:
            density[c], keep[c] = density[donors[0]], keep[donors[0]]
    blobs = [
        (klass[r["terrain_class"]], int(bin_index(float(r["distance_m"]), d_edges)),
         round(float(r["edge_m"]), 3), int(r["rows"]), int(r["cols"]), int(r["cells"]))
        for r in spurious
    ]  # fmt: skip
    if len(blobs) > MAX_BLOBS:  # evenly through the drive: the library keeps the mix of classes
        blobs = [blobs[i] for i in np.linspace(0, len(blobs) - 1, MAX_BLOBS).round().astype(int)]
    return PemParameters(
        distance_edges_m=tuple(float(d) for d in d_edges),
        size_edges_cells=tuple(float(s) for s in s_edges),
        quantile_levels=QUANTILE_LEVELS,
        confirm_distance_m=_table(np.asarray(confirm)),
        confirm_latency_frames=tuple(round(float(v), 6) for v in latency),
        approach_m=APPROACH_M,
        loss_distance_m=_table(np.asarray(loss)) if loss else (),
        p_keep=_table(p_keep),
        p_return=_table(p_return),
        sightings=tuple(tuple(int(v) for v in row) for row in every),
        near_offset_m=_table(np.asarray(near)),
        far_offset_m=_table(np.asarray(far)),
        fa_density_per_m2=_table(density),
        fa_area_m2=tuple(round(float(a), 3) for a in area.sum(axis=1)),
        fa_keep=_table(keep),
        fa_blobs=tuple(tuple(float(v) for v in blob) for blob in blobs),
        border_band_m=float(border_band_m),
        clutter_band_m=float(clutter_band_m),
        rough_relief_m=float(rough_relief_m),
        match_cells=int(match_cells),
    )


def _table(values: Any) -> Any:
    """A (nested) table of floats, rounded to 6 decimals, as nested tuples."""
    values = np.asarray(values)
    if values.ndim == 1:
        return tuple(round(float(v), 6) for v in values)
    return tuple(_table(row) for row in values)


def calibration_factors(sightings_csv: str | Path, distance_edges_m: tuple[float, ...]) -> np.ndarray:
    """On courses driven by both grids, per distance bin the detector's recall over the PEM's; 1
    where either grid has fewer than :data:`CALIBRATION_MIN_COUNT` sightings or the PEM drew none.

    Raises:
        ConfigError: the rows hold no sighting of one of the grids.
    """
    sightings = read_csv(sightings_csv)
    d_edges = np.asarray(distance_edges_m)
    seen, drawn = np.zeros((2, len(d_edges) - 1)), np.zeros((2, len(d_edges) - 1))
    for m, mode in enumerate(MODES):
        rows = [r for r in sightings if r["mode"] == mode]
        if not rows:
            raise ConfigError("sightings", f"{sightings_csv} holds no {mode} sighting to calibrate on")
        d = bin_index(np.array([float(r["centre_m"]) for r in rows]), d_edges)
        np.add.at(seen[m], d, 1.0)
        np.add.at(drawn[m], d, np.array([r["detected"] == "1" for r in rows], dtype=np.float64))
    enough = (seen.min(axis=0) >= CALIBRATION_MIN_COUNT) & (drawn[1] > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(enough, (drawn[0] / seen[0]) / (drawn[1] / seen[1]), 1.0)


def calibrate(parameters: PemParameters, by_bin: np.ndarray) -> PemParameters:
    """``parameters`` with each distance bin's chain shares (``p_keep``, ``p_return``) times
    ``by_bin`` (:func:`calibration_factors`), a share kept within 0 and 1."""

    def chain(table: tuple[tuple[float, ...], ...]) -> tuple[tuple[float, ...], ...]:
        return _table(np.clip(np.asarray(table) * np.asarray(by_bin)[None, :], 0.0, 1.0))

    return dataclasses.replace(
        parameters, p_keep=chain(parameters.p_keep), p_return=chain(parameters.p_return)
    )


#: The tables of a channel that describe its false alarms (and the terrain classes they are per).
FALSE_ALARM_FIELDS: tuple[str, ...] = (
    "fa_density_per_m2",
    "fa_keep",
    "fa_area_m2",
    "fa_blobs",
    "border_band_m",
    "clutter_band_m",
    "rough_relief_m",
)


def with_false_alarms(base: PerceptionErrorModel, fitted: PerceptionErrorModel) -> PerceptionErrorModel:
    """``base`` with the false-alarm tables (:data:`FALSE_ALARM_FIELDS`) of ``fitted`` in each
    channel both model; everything else, and its calibration, stays ``base``'s. Its ``fit`` record
    gains ``false_alarms``, the courses the new tables were fitted on.

    Raises:
        ConfigError: the two were fitted on other detector settings, or on other channels.
    """
    differ = settings_diff(base.fitted_on, fitted.fitted_on)
    if differ or base.channels != fitted.channels:
        raise ConfigError(
            "false_alarms_into",
            "the base model was fitted on other settings or channels: "
            + ("; ".join(differ[:6]) or f"{base.channels} vs {fitted.channels}"),
        )

    def merged(channel: str) -> PemParameters:
        new = fitted.channel_parameters(channel)
        return dataclasses.replace(
            base.channel_parameters(channel), **{f: getattr(new, f) for f in FALSE_ALARM_FIELDS}
        )

    positive = merged("positive") if "positive" in base.channels else None
    return dataclasses.replace(
        base,
        parameters=merged("negative"),
        positive=positive,
        fit={**base.fit, "false_alarms": {k: v for k, v in fitted.fit.items() if k != "calibration_passes"}},
    )


def fit_pem(
    config: PemCampaignConfig,
    model_path: str | Path,
    work_dir: str | Path,
    options: RunOptions | None = None,
    calibration_passes: int = 1,
    false_alarms_into: PerceptionErrorModel | None = None,
) -> PerceptionErrorModel:
    """Drive ``config``'s courses through the detector grid (rows kept in ``work_dir``, resumable),
    fit the PEM of both channels, calibrate it ``calibration_passes`` times on the same courses
    (module docstring; each pass drives them with the PEM, resumable too) and write it to
    ``model_path`` atomically. With ``false_alarms_into``, write that model with only its
    false-alarm tables replaced by this fit's (:func:`with_false_alarms`; no calibration: the
    false alarms do not enter it).

    Raises:
        ConfigError: ``calibration_passes`` is not a whole number >= 0, or > 0 beside
            ``false_alarms_into``; a base model of other settings.
    """
    if (
        isinstance(calibration_passes, bool)
        or not isinstance(calibration_passes, int)
        or calibration_passes < 0
    ):
        raise ConfigError("calibration_passes", f"must be a whole number >= 0, got {calibration_passes!r}")
    if false_alarms_into is not None and calibration_passes:
        raise ConfigError("calibration_passes", "must be 0 with false_alarms_into (the base keeps its chain)")
    csvs = run_pem_campaign(config, work_dir, None, options, "PEM fit courses")
    parameters = {
        channel: fit_parameters(
            csvs[tables["sightings"]],
            csvs[tables["spurious"]],
            csvs[tables["frames"]],
            config.border_band_m,
            config.clutter_band_m,
            config.rough_relief_m,
            confirm_by_size=channel == "positive",
            loss_by_distance=channel == "positive",
            match_cells=config.positive_match_cells if channel == "positive" else 0,
            fragment_m=config.pit_fragment_m if channel == "negative" else 0.0,
        )
        for channel, tables in CHANNEL_TABLES.items()
    }
    frames = sum(config.frames_of(i) for i in range(config.seeds))
    model = PerceptionErrorModel(
        parameters=parameters["negative"],
        positive=parameters["positive"],
        fitted_on=pem_settings(config.observation),
        fit={
            "course": "detection_course",
            "first_seed": config.first_seed,
            "seeds": config.seeds,
            "frames": frames,
            "track_obstacles_per_100m": config.track_obstacles_per_100m,
            "positive_match_cells": config.positive_match_cells,
            "pit_fragment_m": config.pit_fragment_m,
        },
    )
    if false_alarms_into is not None:
        model = with_false_alarms(false_alarms_into, model)
    # the PEM's drives join the detector's in work_dir (keyed by the model), so a pass resumes too
    again = dataclasses.replace(options or RunOptions(), resume=True)
    for k in range(calibration_passes):
        csvs = run_pem_campaign(config, work_dir, model, again, f"PEM calibration pass {k + 1}")
        for channel, tables in CHANNEL_TABLES.items():
            p = model.channel_parameters(channel)
            parameters[channel] = calibrate(
                p, calibration_factors(csvs[tables["sightings"]], p.distance_edges_m)
            )
        model = dataclasses.replace(
            model,
            parameters=parameters["negative"],
            positive=parameters["positive"],
            fit={**model.fit, "calibration_passes": k + 1},
        )
    model.save(model_path)
    return model
