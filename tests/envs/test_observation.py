"""The oracle grid: its culled point-in-polygon test equals testing every cell against every obstacle."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from negobs_gym.core.geometry import pad_polygons, points_in_polygons, vehicle_to_world_xy
from negobs_gym.core.pose import Pose
from negobs_gym.envs.observation import (
    OracleGrid,
    grid_space,
    mirror_signs,
    stack_channels,
    state_fields,
    state_vector,
)
from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.sim.presets import winding_course
from negobs_gym.spec import ObservationConfig


@pytest.fixture(scope="module")
def course():
    return winding_course(120.0, seed=3, resolution_m=0.25)


@pytest.mark.parametrize("station_m", [5.0, 25.0, 47.0, 71.0, 96.0])
def test_oracle_obstacle_layers_equal_the_brute_force_test(course, station_m: float) -> None:
    config = ObservationConfig(source="oracle")
    grid = OracleGrid(config, course)
    line = np.asarray(course.track.centreline_xy_m)
    stations = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))])
    k = int(np.searchsorted(stations, station_m))
    heading = line[k + 1] - line[k]
    pose = Pose(x=float(line[k, 0]), y=float(line[k, 1]), yaw=float(np.arctan2(-heading[0], heading[1])))
    layers = grid.layers(pose)
    cells = vehicle_to_world_xy(config.grid.cell_centres().reshape(-1, 2), (pose.x, pose.y), pose.yaw)
    negatives = pad_polygons([np.asarray(o.outline_xy_m) for o in course.negative_obstacles])
    positives = pad_polygons([o.footprint_xy_m for o in course.positive_obstacles])
    expected_neg = points_in_polygons(cells, negatives).any(axis=1).reshape(config.grid.shape)
    expected_pos = points_in_polygons(cells, positives).any(axis=1).reshape(config.grid.shape)
    np.testing.assert_array_equal(layers["negative"], expected_neg)
    np.testing.assert_array_equal(layers["positive"], expected_pos)


def test_some_view_of_the_course_holds_obstacles(course) -> None:
    """The equality above is not vacuous: the views along the course see obstacles of both kinds."""
    config = ObservationConfig(source="oracle")
    grid = OracleGrid(config, course)
    line = np.asarray(course.track.centreline_xy_m)
    seen_neg = seen_pos = 0
    for k in range(0, len(line) - 1, max(1, len(line) // 40)):
        heading = line[k + 1] - line[k]
        pose = Pose(x=float(line[k, 0]), y=float(line[k, 1]), yaw=float(np.arctan2(-heading[0], heading[1])))
        layers = grid.layers(pose)
        seen_neg += int(layers["negative"].any())
        seen_pos += int(layers["positive"].any())
    assert seen_neg > 0 and seen_pos > 0


def test_oracle_range_blanks_obstacles_beyond_it_and_keeps_the_rest(course) -> None:
    full = OracleGrid(ObservationConfig(source="oracle"), course)
    near = OracleGrid(ObservationConfig(source="oracle", oracle_range_m=14.0), course)
    config = ObservationConfig(source="oracle")
    centres = config.grid.cell_centres()
    inside = np.hypot(centres[..., 0], centres[..., 1]) <= 14.0
    line = np.asarray(course.track.centreline_xy_m)
    cut = 0
    for k in range(0, len(line) - 1, max(1, len(line) // 40)):
        heading = line[k + 1] - line[k]
        pose = Pose(x=float(line[k, 0]), y=float(line[k, 1]), yaw=float(np.arctan2(-heading[0], heading[1])))
        a, b = full.layers(pose), near.layers(pose)
        for name in ("negative", "positive"):
            np.testing.assert_array_equal(b[name], a[name] & inside)
            cut += int((a[name] & ~inside).any())
        np.testing.assert_array_equal(b["traversable"], a["traversable"])
    assert cut > 0  # some obstacle was beyond 14 m in some view


def _views_along(course, every: int = 40):
    """Poses on the centre line facing along it, ``every``-th of the course's views."""
    line = np.asarray(course.track.centreline_xy_m)
    for k in range(0, len(line) - 1, max(1, len(line) // every)):
        heading = line[k + 1] - line[k]
        yield Pose(x=float(line[k, 0]), y=float(line[k, 1]), yaw=float(np.arctan2(-heading[0], heading[1])))


def test_a_subset_of_channels_gives_those_layers_of_the_full_set(course) -> None:
    config = ObservationConfig(source="oracle")
    grid = OracleGrid(config, course)
    for pose in _views_along(course, 12):
        full = grid.layers(pose)
        assert list(full) == ["negative", "positive", "traversable", "observed"]
        for channels in (("negative", "positive"), ("traversable",), ("observed",), ("positive", "observed")):
            part = grid.layers(pose, channels)
            assert list(part) == list(channels)
            for name in channels:
                np.testing.assert_array_equal(part[name], full[name])
    with pytest.raises(ConfigError, match=r"^channels: no grid channel \['lidar'\]") as error:
        grid.layers(pose, ("negative", "lidar"))
    assert error.value.field == "channels" and isinstance(error.value, ValueError)


def test_traversable_cells_are_on_the_track_by_the_full_centre_line_search(course) -> None:
    """The on-track test (a coarse pass, then a search cut off just beyond half the track width
    for the cells near the edge) marks the cells a full search of every sample does: on the
    centre line, beside the track and far from it."""
    config = ObservationConfig(source="oracle")
    grid = OracleGrid(config, course)
    half_width = 0.5 * course.track.width_m
    on_and_off = 0
    views = [
        Pose(x=p.x + dx, y=p.y, yaw=p.yaw + turn)
        for p in _views_along(course)
        for dx, turn in ((0.0, 0.0), (7.0, 0.6), (-60.0, 0.0))
    ]
    for pose in views:
        layers = grid.layers(pose)
        cells = vehicle_to_world_xy(config.grid.cell_centres().reshape(-1, 2), (pose.x, pose.y), pose.yaw)
        on_track = (grid._track_tree.query(cells)[0] <= half_width).reshape(config.grid.shape)
        expected = on_track & ~layers["negative"] & ~layers["positive"] & layers["observed"]
        np.testing.assert_array_equal(layers["traversable"], expected)
        on_and_off += int(on_track.any() and not on_track.all())
    assert on_and_off > 0  # views hold cells on both sides of the edge


def _mirror_about_heading(points: np.ndarray, pose: Pose) -> np.ndarray:
    """World points mirrored about the line through the vehicle along its heading."""
    origin = np.array([pose.x, pose.y])
    right = vehicle_to_world_xy(np.array([[1.0, 0.0]]), origin, pose.yaw)[0] - origin
    return points - 2.0 * np.outer((points - origin) @ right, right)


def test_a_mirrored_scene_reverses_the_grid_columns(course) -> None:
    """Obstacles mirrored about the heading line show up in the same rows, columns reversed: the
    left-right mirror of an observation (policies' demonstration mirroring) is a column flip."""
    config = ObservationConfig(source="oracle")
    line = np.asarray(course.track.centreline_xy_m)
    checked = 0
    for k in range(0, len(line) - 1, max(1, len(line) // 20)):
        heading = line[k + 1] - line[k]
        pose = Pose(x=float(line[k, 0]), y=float(line[k, 1]), yaw=float(np.arctan2(-heading[0], heading[1])))
        mirror = SimpleNamespace(
            negative_obstacles=[
                SimpleNamespace(outline_xy_m=_mirror_about_heading(np.asarray(o.outline_xy_m), pose)[::-1])
                for o in course.negative_obstacles
            ],
            positive_obstacles=[
                SimpleNamespace(footprint_xy_m=_mirror_about_heading(o.footprint_xy_m, pose)[::-1])
                for o in course.positive_obstacles
            ],
            heightfield=course.heightfield,
            track=course.track,
        )
        seen, mirrored = OracleGrid(config, course).layers(pose), OracleGrid(config, mirror).layers(pose)
        for name in ("negative", "positive"):
            np.testing.assert_array_equal(mirrored[name], seen[name][:, ::-1])
            checked += int(seen[name].any())
    assert checked > 0


def test_mirror_signs_negate_the_lateral_state_values() -> None:
    config = ObservationConfig(route_points_m=(5.0, 10.0, 15.0))
    signs = mirror_signs(config)
    fields = state_fields(config)
    assert dict(zip(fields, signs, strict=True)) == {
        "speed_mps": 1, "yaw_rate_rps": -1, "steering_rad": -1, "goal_x_m": -1, "goal_y_m": 1,
        "route_5_x_m": -1, "route_5_y_m": 1, "route_10_x_m": -1, "route_10_y_m": 1,
        "route_15_x_m": -1, "route_15_y_m": 1,
    }  # fmt: skip
    # the state of a mirrored world: goal and route mirrored about the heading, turning the other way
    pose = Pose(x=3.0, y=-2.0, yaw=0.7)
    goal = np.array([40.0, 55.0])
    route = np.array([[6.0, 2.0], [9.0, 6.5], [11.0, 12.0]])
    seen = state_vector(config, pose, 5.0, 0.4, 0.2, goal, route)
    goal_m, route_m = _mirror_about_heading(goal[None], pose)[0], _mirror_about_heading(route, pose)
    mirrored = state_vector(config, pose, 5.0, -0.4, -0.2, goal_m, route_m)
    np.testing.assert_allclose(mirrored, seen * signs, atol=1e-5)
    for wrong in (None, route[:2]):  # the config asks for 3 route points
        with pytest.raises(GeometryError, match=r"^route_xy_m: must have shape \(3, 2\)"):
            state_vector(config, pose, 5.0, 0.4, 0.2, goal, wrong)


def test_a_counting_grid_keeps_how_many_fine_cells_each_block_holds() -> None:
    rng = np.random.default_rng(0)
    config = ObservationConfig(source="oracle", channels=("negative", "positive"), pooling="count")
    layers = {name: rng.random(config.grid.shape) < 0.1 for name in config.channels}
    counted = stack_channels(layers, config)
    most = stack_channels(layers, ObservationConfig(source="oracle", channels=config.channels))
    rows, cols = config.grid.shape
    fine = np.stack([layers[name] for name in config.channels]).astype(int)
    expected = fine.reshape(2, rows // 4, 4, cols // 4, 4).sum(axis=(2, 4))
    np.testing.assert_array_equal(counted, expected)
    assert counted.max() > 1  # some block holds more than one set cell
    np.testing.assert_array_equal(most, counted > 0)  # the maximum is whether any is set
    assert counted.dtype == np.uint8 and grid_space(config).high.max() == 16 == config.grid_max
    assert grid_space(config).contains(counted)
    with pytest.raises(ConfigError, match="pooling"):
        ObservationConfig(pooling="mean")
    with pytest.raises(ConfigError, match="uint8"):
        ObservationConfig(downsample=16, pooling="count")
