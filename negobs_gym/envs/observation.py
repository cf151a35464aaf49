"""Observation builders: the vehicle-centred grid channels and the vehicle state vector."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from negobs_gym.core.geometry import (
    pad_polygons,
    points_in_polygons,
    polyline_stations,
    vehicle_to_world_xy,
    world_to_vehicle_xy,
)
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.sim.types import Terrain
from negobs_gym.spec import CHANNELS, ROUTE_MARGIN_M, ObservationConfig

__all__ = [
    "STATE_FIELDS",
    "OracleGrid",
    "grid_space",
    "mirror_signs",
    "stack_channels",
    "state_fields",
    "state_space",
    "state_vector",
]

#: The first ``state`` values: speed, yaw rate, steering angle, goal vector (vehicle frame); route
#: points follow when the config asks for them (:func:`state_fields`).
STATE_FIELDS: tuple[str, ...] = ("speed_mps", "yaw_rate_rps", "steering_rad", "goal_x_m", "goal_y_m")

#: widens the box around the grid's four corner cells so rounding cannot leave a cell outside [m]
_VIEW_MARGIN_M = 1e-6
#: spacing of the centre-line samples the oracle's on-track test measures to [m]
_TRACK_SPACING_M = 0.05
#: every how many samples the on-track test's first, coarse pass takes one
_COARSE_EVERY = 20
#: above any rounding difference between two ways of computing one distance [m]
_ROUNDING_M = 1e-9


def grid_space(config: ObservationConfig) -> spaces.Box:
    """uint8 grid per channel, shape (channels, rows, cols): 0 = no / 1 = yes, or with
    ``pooling="count"`` the number of fine cells set in each block."""
    return spaces.Box(0, config.grid_max, config.shape, dtype=np.uint8)


def state_fields(config: ObservationConfig) -> tuple[str, ...]:
    """Names of the ``state`` values: :data:`STATE_FIELDS`, then ``route_<d>_x_m, route_<d>_y_m``
    for each of ``config.route_points_m``."""
    route = tuple(f"route_{d:g}_{axis}_m" for d in config.route_points_m for axis in ("x", "y"))
    return STATE_FIELDS + route


def mirror_signs(config: ObservationConfig) -> np.ndarray:
    """float32 sign of each ``state`` value when the scene is mirrored about the vehicle's heading
    line: the lateral values (yaw rate, steering, and the x of the goal and route points, x right)
    change sign, the rest keep it. The grid's mirror image is its columns reversed (the grid is
    centred on the vehicle: ``GridSpec.side_m`` each side)."""
    lateral = ("yaw_rate_rps", "steering_rad")
    return np.array(
        [-1.0 if name in lateral or name.endswith("_x_m") else 1.0 for name in state_fields(config)],
        np.float32,
    )


def state_space(config: ObservationConfig) -> spaces.Box:
    """float32 state in physical units, clipped to the declared bounds."""
    route_bound = (max(config.route_points_m) + ROUTE_MARGIN_M) if config.route_points_m else 0.0
    hi = np.array(
        [config.max_speed_mps, 3.0, 1.0, config.max_goal_distance_m, config.max_goal_distance_m]
        + [route_bound] * (2 * len(config.route_points_m)),
        np.float32,
    )
    return spaces.Box(-hi, hi, dtype=np.float32)


def state_vector(
    config: ObservationConfig,
    pose: Pose,
    speed_mps: float,
    yaw_rate_rps: float,
    steering_rad: float,
    goal_xy_m: np.ndarray,
    route_xy_m: np.ndarray | None = None,
) -> np.ndarray:
    """The ``state`` observation (see :func:`state_fields`); goal and route in the vehicle frame.

    ``route_xy_m``: world xy (len(config.route_points_m), 2) of the route points, needed when the
    config has any.
    """
    origin = (pose.x, pose.y)
    goal_v = world_to_vehicle_xy(np.asarray(goal_xy_m, dtype=np.float64), origin, pose.yaw)
    n_route = len(config.route_points_m)
    if n_route:
        route = np.asarray(route_xy_m, dtype=np.float64) if route_xy_m is not None else None
        if route is None or route.shape != (n_route, 2):
            raise GeometryError(
                f"route_xy_m: must have shape ({n_route}, 2), got {None if route is None else route.shape}"
            )
        route_v = world_to_vehicle_xy(route, origin, pose.yaw).ravel()
    else:
        route_v = np.zeros(0)
    space = state_space(config)
    raw = np.concatenate([[speed_mps, yaw_rate_rps, steering_rad, goal_v[0], goal_v[1]], route_v])
    return np.clip(raw, space.low, space.high).astype(np.float32)


def _pool(grid: np.ndarray, k: int, pooling: str) -> np.ndarray:
    """Pool (C, R, W) 0/1 cells by k x k blocks: their maximum (a one-cell obstacle survives
    down-sampling) or, with ``pooling="count"``, how many are set."""
    if k == 1:
        return grid
    c, r, w = grid.shape
    blocks = grid.reshape(c, r // k, k, w // k, k)
    if pooling == "count":
        return blocks.sum(axis=(2, 4), dtype=np.uint8)
    return blocks.max(axis=(2, 4))


class OracleGrid:
    """Ground-truth grid for ablations: rasterises the terrain's obstacle records around a pose.

    ``negative`` = cell centre inside a negative obstacle outline; ``positive`` = inside a positive
    obstacle footprint (both only within ``config.oracle_range_m`` of the vehicle when set);
    ``traversable`` = on the track and in neither (at any range); ``observed`` = inside the
    heightfield (the oracle sees everything).
    """

    def __init__(self, config: ObservationConfig, terrain: Terrain) -> None:
        if config.source != "oracle":
            raise ConfigError("source", f"OracleGrid needs source='oracle', got {config.source!r}")
        self.config = config
        self.terrain = terrain
        self._neg = pad_polygons([np.asarray(o.outline_xy_m) for o in terrain.negative_obstacles])
        self._pos = (
            pad_polygons([o.footprint_xy_m for o in terrain.positive_obstacles])
            if terrain.positive_obstacles
            else np.zeros((0, 3, 2))
        )
        self._neg_boxes = _bounding_boxes(self._neg)
        self._pos_boxes = _bounding_boxes(self._pos)
        centres = config.grid.cell_centres()
        self.cell_centres_v = centres.reshape(-1, 2)  # (P, 2), row-major: the layers' cells, flattened
        self._corners_v = centres[[0, 0, -1, -1], [0, -1, 0, -1]]  # the lattice's extremes lie here
        self._in_range = (
            np.hypot(self.cell_centres_v[:, 0], self.cell_centres_v[:, 1]) <= config.oracle_range_m
            if config.oracle_range_m is not None
            else np.ones(len(self.cell_centres_v), dtype=bool)
        )
        self._track_tree = _centreline_tree(np.asarray(terrain.track.centreline_xy_m, dtype=np.float64))
        samples = self._track_tree.data
        every = _COARSE_EVERY
        self._coarse = samples[np.unique(np.r_[np.arange(0, len(samples), every), len(samples) - 1])]
        # a sample is at most every // 2 samples along the line from a coarse one, so within this
        self._coarse_reach_m = (every // 2) * _TRACK_SPACING_M

    def layers(self, pose: Pose, channels: Sequence[str] = CHANNELS) -> dict[str, np.ndarray]:
        """Full-resolution bool layers around ``pose``, for the named ``channels`` only (an
        observation of ``negative`` and ``positive`` skips the track and heightfield lookups)."""
        unknown = set(channels) - set(CHANNELS)
        if unknown:
            raise ConfigError("channels", f"no grid channel {sorted(unknown)}; one of {CHANNELS}")
        shape = self.config.grid.shape
        pts = vehicle_to_world_xy(self.cell_centres_v, (pose.x, pose.y), pose.yaw)
        corners = vehicle_to_world_xy(self._corners_v, (pose.x, pose.y), pose.yaw)
        view = corners.min(axis=0) - _VIEW_MARGIN_M, corners.max(axis=0) + _VIEW_MARGIN_M  # holds pts
        layers: dict[str, np.ndarray] = {}
        if {"negative", "positive", "traversable"} & set(channels):
            neg = _inside_any(pts, self._neg, self._neg_boxes, view)
            pos = _inside_any(pts, self._pos, self._pos_boxes, view)
            layers["negative"], layers["positive"] = neg & self._in_range, pos & self._in_range
        if {"traversable", "observed"} & set(channels):
            layers["observed"] = np.isfinite(self.terrain.heightfield.height_at(pts))
        if "traversable" in channels:
            layers["traversable"] = self._on_track(pts, view) & ~neg & ~pos & layers["observed"]
        return {name: layers[name].reshape(shape) for name in channels}

    def _on_track(self, points_xy: np.ndarray, view: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """Bool (P,): the nearest centre-line sample within half the track width (``view``: a box
        holding the points).

        The same answer as a search of every sample, for a fraction of the work: the distance d
        to the nearest coarse sample (every 20th) bounds the nearest sample's, between d - reach
        and d, so only the points in that band around the edge are searched (in the KD-tree, cut
        off just beyond half the width); the coarse samples beyond reach of the view are skipped.
        """
        half = 0.5 * self.terrain.track.width_m
        reach = self._coarse_reach_m
        # a coarse sample farther than half + reach from every point decides nothing (+ 1 m of room)
        slack = half + reach + 1.0
        lo, hi = view[0] - slack, view[1] + slack
        coarse = self._coarse[np.all((self._coarse >= lo) & (self._coarse <= hi), axis=1)]
        if len(coarse) == 0:
            return np.zeros(len(points_xy), dtype=bool)
        x, y = points_xy[:, 0], points_xy[:, 1]
        d_sq = np.full(len(points_xy), np.inf)
        for sx, sy in coarse:  # tens of samples in view; the points are vectorised
            np.minimum(d_sq, (x - sx) ** 2 + (y - sy) ** 2, out=d_sq)
        d = np.sqrt(d_sq)
        on_track = d <= half - _ROUNDING_M
        band = np.flatnonzero(~on_track & (d <= half + reach + _ROUNDING_M))
        lateral, _ = self._track_tree.query(points_xy[band], distance_upper_bound=half + 0.1)
        on_track[band] = lateral <= half
        return on_track

    def observe(self, pose: Pose) -> np.ndarray:
        """uint8 (channels, rows, cols) grid around ``pose`` (:func:`stack_channels`)."""
        return stack_channels(self.layers(pose), self.config)


def _bounding_boxes(polygons: np.ndarray) -> np.ndarray:
    """(M, 4) xmin, ymin, xmax, ymax of padded polygons (M, N, 2)."""
    if polygons.shape[0] == 0:
        return np.zeros((0, 4))
    return np.concatenate([polygons.min(axis=1), polygons.max(axis=1)], axis=1)


def _inside_any(
    points_xy: np.ndarray, polygons: np.ndarray, boxes: np.ndarray, view: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    """Bool (P,): point inside any of the polygons. Only polygons whose box meets ``view``, a box
    around the points, are tested, each against the points inside its own box (a course's
    obstacles are mostly out of view)."""
    inside = np.zeros(len(points_xy), dtype=bool)
    lo, hi = view
    near = np.nonzero(
        (boxes[:, 0] <= hi[0]) & (boxes[:, 2] >= lo[0]) & (boxes[:, 1] <= hi[1]) & (boxes[:, 3] >= lo[1])
    )[0]
    x, y = points_xy[:, 0], points_xy[:, 1]
    for k in near:  # loop over the few obstacles in view; the points are vectorised
        idx = np.nonzero((x >= boxes[k, 0]) & (x <= boxes[k, 2]) & (y >= boxes[k, 1]) & (y <= boxes[k, 3]))[0]
        if idx.size:
            inside[idx] |= points_in_polygons(points_xy[idx], polygons[k : k + 1])[:, 0]
    return inside


def stack_channels(layers: dict[str, np.ndarray], config: ObservationConfig) -> np.ndarray:
    """uint8 (channels, rows, cols) observation from full-resolution layers, pooled."""
    grid = np.stack([layers[name] for name in config.channels]).astype(np.uint8)
    return _pool(grid, config.downsample, config.pooling)


def _centreline_tree(polyline: np.ndarray, spacing_m: float = _TRACK_SPACING_M):
    """KD-tree of the centre line resampled every ``spacing_m``: nearest-sample distance is the
    lateral distance to within ``spacing_m / 2`` (fine for 20 cm cells)."""
    from scipy.spatial import cKDTree

    stations = polyline_stations(polyline)
    s = np.arange(0.0, stations[-1] + spacing_m, spacing_m)
    xy = np.stack([np.interp(s, stations, polyline[:, 0]), np.interp(s, stations, polyline[:, 1])], axis=1)
    return cKDTree(xy)
