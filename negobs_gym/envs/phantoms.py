"""Phantom ``negative`` clusters for an oracle grid: the detectors' false pits, beside the track.

A policy trained on the ground truth has never seen a ``negative`` cluster where no pit lies, and
stands still when the detector grid shows one (docs/notebook/training_studies.md, "Open"). Phantoms put
such clusters into the oracle grid: rectangles fixed in the world beyond the track's edges that
show, flickering, only at the distances where the detectors report theirs
(:class:`~negobs_gym.envs.config.PhantomConfig`).
"""

from __future__ import annotations

import numpy as np

from negobs_gym.core.geometry import distance_to_polyline, vehicle_to_world_xy, world_to_vehicle_xy
from negobs_gym.core.pose import Pose
from negobs_gym.sim.types import Track
from negobs_gym.spec import PhantomConfig

__all__ = ["Phantoms"]


class Phantoms:
    """One episode's phantoms: drawn from ``rng`` at construction, shown per frame from it too.

    Attributes:
        centres_xy_m: World xy (K, 2) of the rectangles' centres.
        yaws_rad: Their headings (the track's at their station; yaw 0 faces world +Y).
        half_sizes_m: (K, 2) half lengths across and along the track.
    """

    def __init__(self, config: PhantomConfig, track: Track, rng: np.random.Generator) -> None:
        self.config = config
        self._rng = rng
        length = track.length_m
        count = int(rng.poisson(config.per_100m * length / 100.0))
        stations = rng.uniform(0.0, length, count)
        sides = rng.choice(np.array([-1.0, 1.0]), count)
        beyond = rng.uniform(*config.beyond_edge_m, count)
        sizes = np.stack([rng.uniform(*config.across_m, count), rng.uniform(*config.along_m, count)], axis=-1)
        centres, yaws = track.pose_at(stations, sides * (0.5 * track.width_m + beyond + 0.5 * sizes[:, 0]))
        # in a bend, a point beside one stretch can lie on another: keep the ones off the track
        off_track = distance_to_polyline(centres, track.centreline_xy_m) >= 0.5 * (
            track.width_m + sizes[:, 0]
        )
        self.centres_xy_m = centres[off_track].reshape(-1, 2)
        self.yaws_rad = np.asarray(yaws)[off_track].reshape(-1)
        self.half_sizes_m = 0.5 * sizes[off_track].reshape(-1, 2)

    def __len__(self) -> int:
        return len(self.centres_xy_m)

    def layer(self, pose: Pose, cell_centres_v: np.ndarray) -> np.ndarray:
        """Bool (P,): which of the vehicle-frame cell centres (P, 2) a phantom showing this frame
        covers. Draws one number per phantom from the episode's generator every call, so the
        stream does not depend on where the vehicle is."""
        shown = self._rng.random(len(self)) < self.config.show_probability
        inside = np.zeros(len(cell_centres_v), dtype=bool)
        if not shown.any():
            return inside
        distance = np.hypot(self.centres_xy_m[:, 0] - pose.x, self.centres_xy_m[:, 1] - pose.y)
        low, high = self.config.range_m
        visible = np.nonzero(shown & (distance >= low) & (distance <= high))[0]
        if visible.size == 0:
            return inside
        points = vehicle_to_world_xy(cell_centres_v, (pose.x, pose.y), pose.yaw)
        for k in visible:  # the few phantoms in view; the cells are vectorised
            local = world_to_vehicle_xy(
                points, self.centres_xy_m[k], float(self.yaws_rad[k])
            )  # x across, y along
            inside |= np.all(np.abs(local) <= self.half_sizes_m[k], axis=1)
        return inside
