"""Recall of the detector on a recorded drive whose negative obstacles were surveyed (paper N
§4.2's matching and Table 7 layout, as the simulated campaigns count them; docs/eval.md).

The surveyed outlines are a JSON file, ``{"negative_obstacles": [{"name": "...", "outline_xy_m":
[[x, y], ...]}, ...]}``: each outline's ground polygon in metres in the world frame of the drive's
poses, i.e. the fixed frame (``odom``, ``map``) of the poses file, topic or transform tree, in its
own ROS axes. Each frame maps them into the vehicle frame at the frame's pose and matches them with
the detected outlines on the 20 cm grid (:func:`~negobs_gym.eval.detection.match_frame`). A drive
read without poses stands at the world origin facing its x axis (ROS: x forward, y left).
Pure numpy; no simulator import.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError
from negobs_gym.eval.detection import (
    DetectionEvalConfig,
    RecallTable,
    distance_bins,
    match_frame,
    world_outline_to_vehicle,
)
from negobs_gym.eval.tables import bin_labels, key_value_table, recall_table

__all__ = ["RecordedRecall", "SurveyedObstacle", "read_surveyed_obstacles"]

#: The pose of a drive read without poses: at the world origin, facing the world's x axis (ROS),
#: i.e. this package's yaw -90 deg (its vehicle Y is forward).
STANDING_POSE = Pose(yaw=-math.pi / 2)
FORMAT = '{"negative_obstacles": [{"name": ..., "outline_xy_m": [[x, y], ...]}, ...]}'


@dataclass(frozen=True, eq=False)
class SurveyedObstacle:
    """One surveyed negative obstacle: a name and its ground outline (N, 2) in the world frame."""

    name: str
    outline_xy_m: np.ndarray


def read_surveyed_obstacles(path: str | os.PathLike[str]) -> list[SurveyedObstacle]:
    """The obstacles of a survey file (module note).

    Raises:
        ConfigError: an unreadable file, no ``negative_obstacles`` list, or an outline that is not
            three or more finite (x, y) points (named by its index and name).
    """
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, json.JSONDecodeError) as error:
        raise ConfigError(name, f"not a readable JSON file ({error})") from error
    items = data.get("negative_obstacles") if isinstance(data, dict) else None
    if not isinstance(items, list):
        raise ConfigError(name, f"wants {FORMAT}")
    obstacles = []
    for i, item in enumerate(items):
        where = f"negative_obstacles[{i}]"
        label = item.get("name", where) if isinstance(item, dict) else where
        try:
            outline = np.asarray(item["outline_xy_m"], dtype=np.float64)
        except (TypeError, KeyError, ValueError) as error:
            raise ConfigError(name, f"{where} ({label}): no outline_xy_m of numbers") from error
        if outline.ndim != 2 or outline.shape[1] != 2 or len(outline) < 3 or not np.isfinite(outline).all():
            raise ConfigError(name, f"{where} ({label}): outline_xy_m must be 3 or more finite [x, y] points")
        obstacles.append(SurveyedObstacle(str(label), outline))
    return obstacles


@dataclass
class RecordedRecall:
    """Matches each frame's detected outlines with the surveyed obstacles and counts them in paper N
    Table 7's bins (:class:`RecallTable`), and per distance bin over all sizes."""

    obstacles: Sequence[SurveyedObstacle]
    grid: GridSpec = field(default_factory=GridSpec)
    config: DetectionEvalConfig = field(default_factory=DetectionEvalConfig)

    def __post_init__(self) -> None:
        self.table = RecallTable(self.config)
        n = len(self.config.distance_bin_edges_m) - 1
        self.seen_by_distance = np.zeros(n, dtype=np.int64)
        self.recalled_by_distance = np.zeros(n, dtype=np.int64)
        self.per_obstacle = {o.name: [0, 0] for o in self.obstacles}  # frames in a bin, recalled

    def add(self, detected_outlines: Sequence[np.ndarray], pose: Pose | None) -> dict[str, Any]:
        """Judge one frame (``pose`` None: standing, :data:`STANDING_POSE`); its JSON-ready record:
        per obstacle in the grid its cells, distances and whether a detection overlaps it, and the
        frame's false alarms (detections that overlap no surveyed obstacle)."""
        at = STANDING_POSE if pose is None else pose
        truth = [world_outline_to_vehicle(o.outline_xy_m, at) for o in self.obstacles]
        match = match_frame(list(detected_outlines), truth, self.grid, self.config)
        self.table.add(match)
        d = distance_bins(match, self.config)
        binned = (d >= 0) & (d < self.seen_by_distance.size)
        np.add.at(self.seen_by_distance, d[binned], 1)
        np.add.at(self.recalled_by_distance, d[binned], match.truth_recalled[binned].astype(np.int64))
        for k in np.flatnonzero(binned):
            self.per_obstacle[self.obstacles[k].name][0] += 1
            self.per_obstacle[self.obstacles[k].name][1] += int(match.truth_recalled[k])
        return {
            "obstacles": [
                {
                    "name": o.name,
                    "cells": int(match.truth_cells[k]),
                    "centre_distance_m": round(float(match.truth_centre_distance_m[k]), 3),
                    "nearest_distance_m": round(float(match.truth_distance_m[k]), 3),
                    "recalled": bool(match.truth_recalled[k]),
                }
                for k, o in enumerate(self.obstacles)
                if match.truth_cells[k] > 0
            ],
            "false_alarms": match.false_alarms,
            "detections": match.detections,
        }

    def summary(self) -> dict[str, Any]:
        """Counts and recall per distance bin (all sizes) and per Table 7 bin, per obstacle, and the
        false alarms (NaN recall as None)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            by_distance = self.recalled_by_distance / self.seen_by_distance
        return {
            "frames": self.table.frames,
            "distance_bins": bin_labels(self.config.distance_bin_edges_m, " m"),
            "seen_by_distance": self.seen_by_distance.tolist(),
            "recalled_by_distance": self.recalled_by_distance.tolist(),
            "recall_by_distance": [None if math.isnan(v) else float(v) for v in by_distance],
            "size_bins": bin_labels(self.config.size_bin_edges_cells),
            "seen": self.table.seen.tolist(),
            "recalled": self.table.recalled.tolist(),
            "per_obstacle": {k: {"frames": n, "recalled": r} for k, (n, r) in self.per_obstacle.items()},
            "false_alarms": self.table.false_alarms,
            "false_alarms_per_frame": self.table.false_alarms_per_frame(),
        }

    def markdown(self) -> str:
        """Recall by distance (all sizes), paper N Table 7's layout beside the paper's values, and
        the false alarms."""
        s = self.summary()
        columns = ("distance_bins", "seen_by_distance", "recalled_by_distance", "recall_by_distance")
        table = zip(*(s[c] for c in columns), strict=True)
        rows = [[label, n, r, "-" if v is None else v] for label, n, r, v in table]
        return (
            "\n\n".join(
                [
                    f"Recall on {s['frames']} recorded frames ({len(self.obstacles)} surveyed obstacles)",
                    key_value_table(["distance", "obstacle-frames", "recalled", "recall"], rows),
                    "Table 7 layout (ours (paper N)):",
                    recall_table(self.table.recall(), s["size_bins"], s["distance_bins"]),
                    f"False alarms: {s['false_alarms']} ({s['false_alarms_per_frame']:.3f} per frame)",
                ]
            )
            + "\n"
        )
