"""What ``negobs detect`` writes per frame: a JSON record and a top-down PNG (matplotlib Agg)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io import RecordedFrame
from negobs_gym.detector.io.sync import SynchronisedFrames
from negobs_gym.detector.negative import Detection
from negobs_gym.detector.traversable import TraversableRegion
from negobs_gym.detector.traversable.boundaries import BoundaryLine


def _xyz(a: np.ndarray) -> list[list[float]]:
    return np.round(np.asarray(a, dtype=np.float64), 4).tolist()


def detection_record(
    frame: RecordedFrame,
    sensor: str,
    pose: Pose | None = None,
    *,
    detection: Detection | None = None,
    structure: np.ndarray | None = None,
    region: TraversableRegion | None = None,
    grid: GridSpec | None = None,
) -> dict[str, Any]:
    """JSON-ready record of one update: provenance, then what each detector that ran found.

    Paper N (``detection``, with the structure channel's cells ``structure``, a bool grid of the
    same spec: returns above paper N's ground map, :mod:`negobs_gym.detector.structure`): this
    frame's pairs, fused pairs, obstacles and grid, as top-level keys. Paper T (``region``, on
    ``grid``, the default spec when None): the ``traversable`` key (:func:`traversable_record`).

    Coordinates are metres in the vehicle frame (X right, Y forward, Z up); a grid is given by its
    spec and the ``[row, col]`` of every occupied cell (row 0 = rear edge, col 0 = left edge).
    ``pose`` (``--poses``) is recorded as this package's pose of the vehicle (x, y, z, roll, pitch,
    yaw; vehicle Y forward), None when the frames were taken as standing still.
    """
    record: dict[str, Any] = {
        "source": frame.source,
        "frame": frame.index,
        "timestamp_s": frame.scan.timestamp_s,
        "sensor": sensor,
        "height_m": float(frame.scan.translation_m[2]),
        "mounting": _mounting(frame.scan),
        "ring_source": frame.ring_source,
        "n_points": frame.n_points,
        "scan_shape": list(frame.scan.shape),
        "pose": None if pose is None else [pose.x, pose.y, pose.z, pose.roll, pose.pitch, pose.yaw],
    }
    if detection is not None:
        record.update(_negative_record(detection, structure))
    if region is not None:
        record["traversable"] = traversable_record(region, grid or GridSpec())
    return record


def _negative_record(detection: Detection, structure: np.ndarray | None) -> dict[str, Any]:
    """Paper N's part of a record: pairs, fused pairs, obstacles, grid, structure cells."""
    spec = detection.grid_spec
    fused = detection.pairs
    return {
        "n_frame_pairs": int(sum(len(p) for p in detection.frame_pairs.values())),
        "frame_pairs": {
            name: {"a_m": _xyz(p.a_m), "b_m": _xyz(p.b_m), "c_m": _xyz(np.nan_to_num(p.c_m, nan=0.0))}
            for name, p in detection.frame_pairs.items()
        },
        "fused_pairs": {
            "a_m": _xyz(fused.a_m),
            "b_m": _xyz(fused.b_m),
            "posterior": np.round(fused.posterior, 6).tolist(),
            "confirmed": np.asarray(fused.confirmed, dtype=bool).tolist(),
        },
        "n_obstacles": len(detection.obstacles),
        "obstacles": [
            {
                "outline_xy_m": _xyz(ob.outline_xy_m),
                "centre_xy_m": _xyz(ob.centre_xy_m),
                "area_m2": round(float(ob.area_m2), 4),
                "n_pairs": int(ob.n_pairs),
            }
            for ob in detection.obstacles
        ],
        "grid": _grid(spec, detection.grid),
        "structure_cells": [] if structure is None else np.argwhere(structure).tolist(),
    }


def _grid(spec: GridSpec, occupied: np.ndarray | None = None) -> dict[str, Any]:
    """A grid's spec, with the ``[row, col]`` of each ``occupied`` cell when given."""
    grid: dict[str, Any] = {
        "cell_m": spec.cell_m,
        "ahead_m": spec.ahead_m,
        "back_m": spec.back_m,
        "side_m": spec.side_m,
        "shape": list(spec.shape),
    }
    if occupied is not None:
        grid["occupied_cells"] = np.argwhere(occupied).tolist()
    return grid


def _points_or_none(points: np.ndarray) -> list[list[float] | None]:
    """(k, 2) boundary points, a row with NaN (none found) as None."""
    return [_xyz(p) if np.isfinite(p).all() else None for p in np.asarray(points, dtype=np.float64)]


def _line(line: BoundaryLine | None) -> dict[str, float] | None:
    return None if line is None else {"slope": round(line.slope, 6), "offset_m": round(line.offset_m, 4)}


def traversable_record(region: TraversableRegion, spec: GridSpec) -> dict[str, Any]:
    """Paper T's part of a record: this scan's boundary points per boundary layer (``raw_*``, None
    where a layer has none), the Kalman-filtered ones, the least-squares boundary lines ``x = slope
    * y + offset_m`` (None: a side never seen), the region's polygon, the obstacle clusters, and the
    cells of the traversable, positive-obstacle and reachable (Eq. 13) grids on ``spec``."""
    return {
        "grid": _grid(spec),
        "left_line": _line(region.left_line),
        "right_line": _line(region.right_line),
        "raw_left_m": _points_or_none(region.raw_left_m),
        "raw_right_m": _points_or_none(region.raw_right_m),
        "left_points_m": _points_or_none(region.left_points_m),
        "right_points_m": _points_or_none(region.right_points_m),
        "polygon_m": _xyz(region.polygon_m),
        "n_obstacles": len(region.obstacles),
        "obstacles": [
            {
                "centre_xy_m": _xyz(ob.centre_xy_m),
                "width_m": round(float(ob.width_m), 4),
                "n_points": len(ob.points_m),
            }
            for ob in region.obstacles
        ],
        "traversable_cells": np.argwhere(region.traversable).tolist(),
        "positive_cells": np.argwhere(region.positive_obstacles).tolist(),
        "reachable_cells": np.argwhere(region.reachable).tolist(),
    }


def cloud_records(
    update: SynchronisedFrames, sensors: Mapping[str, str], motions: Mapping[str, np.ndarray | None]
) -> list[dict[str, Any]]:
    """Each topic's cloud in a ``--cloud`` update: topic, ``--sensor`` name, detector input, frame,
    time and offset from the lead's [s], its recorded mounting, and the vehicle's motion from its
    time to the lead's that placed its returns (``[M | m]`` as ``rotation`` and ``translation_m``;
    None without timed poses)."""
    records = []
    for topic, frame in update.clouds.items():
        motion = motions[topic]
        records.append(
            {
                "topic": topic,
                "sensor": sensors[topic],
                "input": frame.scan.sensor,
                "frame": frame.index,
                "timestamp_s": frame.scan.timestamp_s,
                "dt_s": round(frame.scan.timestamp_s - update.time_s, 6),
                "n_points": frame.n_points,
                "ring_source": frame.ring_source,
                "mounting": _mounting(frame.scan),
                "motion": None
                if motion is None
                else {"rotation": motion[:, :3].tolist(), "translation_m": motion[:, 3].tolist()},
            }
        )
    return records


def _mounting(scan: StructuredScan) -> dict[str, Any]:
    """Paper N Eq. 9: the sensor-to-vehicle rotation R and translation T."""
    return {
        "rotation": np.asarray(scan.rotation, dtype=np.float64).tolist(),
        "translation_m": np.asarray(scan.translation_m, dtype=np.float64).tolist(),
    }


#: Pixel of the PNG's height image [m]: about one screen pixel of the figure over the grid's extent.
PIXEL_M = 0.05


def _highest_return(pts: np.ndarray, extent: tuple[float, float, float, float], pixel_m: float) -> np.ndarray:
    """The height of the highest return in each ``pixel_m`` pixel over ``extent`` (x0, x1, y0, y1),
    masked where there is none: the returns drawn top-down as one image rather than a marker each,
    which matplotlib takes most of a frame's PNG time to draw."""
    x0, x1, y0, y1 = extent
    shape = (int(np.ceil((y1 - y0) / pixel_m)), int(np.ceil((x1 - x0) / pixel_m)))
    rows = np.clip(((pts[:, 1] - y0) / pixel_m).astype(np.int64), 0, shape[0] - 1)
    cols = np.clip(((pts[:, 0] - x0) / pixel_m).astype(np.int64), 0, shape[1] - 1)
    image = np.full(shape, np.nan)
    order = np.argsort(pts[:, 2], kind="stable")  # the highest written last
    image[rows[order], cols[order]] = pts[order, 2]
    return np.ma.masked_invalid(image)


def plot_detection(
    frame: RecordedFrame,
    out_path: Path,
    scans: Iterable[StructuredScan] | None = None,
    *,
    detection: Detection | None = None,
    structure: np.ndarray | None = None,
    region: TraversableRegion | None = None,
    grid: GridSpec | None = None,
) -> None:
    """Top-down PNG of one update over the grid's extent: returns coloured by height above ground
    (``scans``' or the frame's); paper N's structure cells (grey), grid cells (yellow), this
    frame's pairs A->B (red), confirmed fused pairs (orange) and obstacle outlines (cyan); paper
    T's traversable cells (green), positive-obstacle cells (white) and boundary lines (lime)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    spec = detection.grid_spec if detection is not None else grid or GridSpec()
    pts = np.concatenate([scan.points_vehicle[scan.valid] for scan in scans or (frame.scan,)])
    inside = (np.abs(pts[:, 0]) <= spec.side_m) & (pts[:, 1] >= -spec.back_m) & (pts[:, 1] <= spec.ahead_m)
    pts = pts[inside]
    fig = Figure(figsize=(7, 9), dpi=110)
    ax = fig.add_subplot()
    ax.set_facecolor("black")
    extent = (-spec.side_m, spec.side_m, -spec.back_m, spec.ahead_m)
    heights = ax.imshow(
        _highest_return(pts, extent, PIXEL_M),
        origin="lower",
        extent=extent,
        cmap="viridis",
        vmin=-1.0,
        vmax=1.5,
        interpolation="nearest",
    )
    fig.colorbar(heights, ax=ax, shrink=0.6, label="height above ground [m] (vehicle frame)")
    title = [f"{Path(frame.source).name} frame {frame.index}: rings from {frame.ring_source}"]
    if region is not None:
        _cells(ax, region.traversable, extent, "green", 0.35)
        _cells(ax, region.positive_obstacles, extent, "white", 0.8)
        ys = np.array([0.0, spec.ahead_m])
        lines = [
            np.column_stack([line.x_at(ys), ys]) for line in (region.left_line, region.right_line) if line
        ]
        ax.add_collection(LineCollection(lines, colors="lime", linewidths=1.2))
        title.append(
            f"paper T: {int(region.traversable.sum())} traversable cells (green), "
            f"{len(region.obstacles)} obstacles (white), {len(lines)} boundaries (lime)"
        )
    if detection is not None:
        if structure is not None:
            _cells(ax, structure, extent, "darkgrey", 0.5)
        _cells(ax, detection.grid, extent, "yellow", 0.6)
        ok = np.asarray(detection.pairs.confirmed, dtype=bool)
        segments = [
            (
                np.concatenate([p.a_m[:, :2] for p in detection.frame_pairs.values()] or [np.empty((0, 2))]),
                np.concatenate([p.b_m[:, :2] for p in detection.frame_pairs.values()] or [np.empty((0, 2))]),
                "red",
                0.8,
            ),
            (detection.pairs.a_m[ok, :2], detection.pairs.b_m[ok, :2], "orange", 1.2),
        ]
        for a, b, colour, width in segments:
            ax.add_collection(LineCollection(np.stack([a, b], axis=1), colors=colour, linewidths=width))
        outlines = [np.vstack([ob.outline_xy_m, ob.outline_xy_m[:1]]) for ob in detection.obstacles]
        ax.add_collection(LineCollection(outlines, colors="cyan", linewidths=1.5))
        n_pairs = sum(len(p) for p in detection.frame_pairs.values())
        n_structure = 0 if structure is None else int(structure.sum())
        title.append(
            f"paper N: {n_pairs} pairs (red), {int(ok.sum())} confirmed (orange), "
            f"{len(detection.obstacles)} obstacles (cyan), {n_structure} structure cells (grey)"
        )
    ax.plot([0], [0], marker="^", color="white", ms=8)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("X right [m]")
    ax.set_ylabel("Y forward [m]")
    ax.set_title("\n".join(title), fontsize=8)
    fig.savefig(out_path, format="png")


def _cells(ax: Any, cells: np.ndarray, extent: tuple[float, ...], colour: str, alpha: float) -> None:
    """Draw the set cells of a bool grid over ``extent`` in one colour."""
    from matplotlib.colors import ListedColormap

    shown = np.ma.masked_where(~cells, np.ones(cells.shape))
    ax.imshow(
        shown,
        origin="lower",
        extent=extent,
        cmap=ListedColormap([colour]),
        alpha=alpha,
        interpolation="nearest",
    )
