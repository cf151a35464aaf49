"""The PEM's terrain classes from the terrain record, and its false alarms born by class."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from negobs_gym.core.geometry import world_to_vehicle_xy
from negobs_gym.core.pose import Pose
from negobs_gym.envs.pem import (
    TERRAIN_CLASSES,
    ClassRaster,
    PemGrid,
    centreline_tree,
    clutter_distance_m,
    ground_relief_m,
    terrain_classes,
)
from negobs_gym.sim.carving import PositiveObstacleSpec
from negobs_gym.sim.terrain import BorderConfig, TerrainConfig, generate_terrain
from negobs_gym.spec import ObservationConfig
from tests.envs.test_pem_model import constant_model

ROCK_STATION_M, ROCK_LATERAL_M = 15.0, 4.5  # the rock's centre: 1.5 m beyond the right edge
MOUND_STATION_M = 22.0  # a 4 x 3 m mound, its centre 3 m beyond the left edge


@pytest.fixture(scope="module")
def terrain():
    """A 30 m straight track along +Y (width 6 m): a bank on the left, a plain verge on the right
    with one rock on it, and a mound beyond the bank."""
    config = TerrainConfig(
        length_m=30.0,
        corridor_width_m=20.0,
        left_border=BorderConfig(kind="bank"),
        positive_obstacles=(
            PositiveObstacleSpec(kind="rock", station_m=ROCK_STATION_M, lateral_m=ROCK_LATERAL_M),
            PositiveObstacleSpec(kind="mound", station_m=MOUND_STATION_M, lateral_m=-6.0),
        ),
    )
    return generate_terrain(config, 0)


def _at(terrain, station_m, lateral_m):
    xy, _ = terrain.track.pose_at(np.asarray(station_m, float), np.asarray(lateral_m, float))
    return np.atleast_2d(xy)


def test_classes_follow_the_track_the_border_kinds_and_the_clutter(terrain):
    tree = centreline_tree(terrain)
    names = ("track", "track", "verge", "bank", "smooth", "clutter", "clutter", "smooth", "mound", "mound")
    stations = (5.0, 15.0, 5.0, 5.0, 5.0, ROCK_STATION_M, ROCK_STATION_M + 0.8, ROCK_STATION_M + 4.0)
    laterals = (0.0, 2.9, 3.5, -5.0, 5.0, ROCK_LATERAL_M, ROCK_LATERAL_M + 0.6, ROCK_LATERAL_M)
    stations += (MOUND_STATION_M, MOUND_STATION_M + 2.3)
    laterals += (-6.0, -6.0)
    points = _at(terrain, stations, laterals)
    got = terrain_classes(points, terrain, tree, band_m=1.0, clutter_band_m=0.6, rough_relief_m=10.0)
    assert [TERRAIN_CLASSES[k] for k in got] == list(names)
    # the plain verge's side beyond the band is rough where its relief reaches rough_relief_m
    relief = ground_relief_m(points, terrain)
    assert 0.0 < relief[4] < 10.0
    plain = terrain_classes(points[[4, 7]], terrain, tree, 1.0, 0.6, rough_relief_m=float(relief[4]))
    assert TERRAIN_CLASSES[plain[0]] == "rough"
    assert TERRAIN_CLASSES[plain[1]] == ("rough" if relief[7] >= relief[4] else "smooth")
    # the track stays the track beside a rock; with no band only the rock's footprint is clutter
    assert (
        TERRAIN_CLASSES[terrain_classes(_at(terrain, 15.0, 2.5), terrain, tree, 1.0, 2.0, 10.0)[0]] == "track"
    )
    bare = terrain_classes(points, terrain, tree, 1.0, 0.0, 10.0) == TERRAIN_CLASSES.index("clutter")
    assert bare.tolist() == [False] * 5 + [True] + [False] * 4
    # the rock's footprint is 0 m away, a point 1 m beyond its side ~1 m
    rock = [o for o in terrain.positive_obstacles if o.kind == "rock"]
    d = clutter_distance_m(
        _at(terrain, [ROCK_STATION_M] * 2, [ROCK_LATERAL_M, ROCK_LATERAL_M + 1.3]), rock, 5.0
    )
    assert d[0] == 0.0 and d[1] == pytest.approx(1.0, abs=0.05)
    raster = ClassRaster.build(terrain, tree, 1.0, 0.6, 10.0)
    assert np.array_equal(raster.at(points[[0, 3, 5, 8]]), got[[0, 3, 5, 8]])


def test_false_alarms_of_the_clutter_class_are_born_near_the_clutter(terrain):
    base = constant_model(0.0).parameters
    density = np.zeros((len(TERRAIN_CLASSES), 2))
    density[TERRAIN_CLASSES.index("clutter")] = 0.5
    clutter_blob = (float(TERRAIN_CLASSES.index("clutter")), 0.0, 1.0, 1.0, 1.0, 1.0)
    params = dataclasses.replace(base, fa_density_per_m2=tuple(map(tuple, density)), fa_blobs=(clutter_blob,))
    model = dataclasses.replace(constant_model(0.0), parameters=params)
    grid = ObservationConfig().grid
    xy, yaw = terrain.track.pose_at(np.array(8.0), np.array(0.0))
    pose = Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw))
    layers = [PemGrid(model, grid, terrain, np.random.default_rng(seed)).layer(pose) for seed in (1, 1, 2)]
    assert np.array_equal(layers[0], layers[1]) and not np.array_equal(layers[0], layers[2])
    rows, cols = np.nonzero(layers[0])
    assert rows.size > 0
    cells = np.column_stack(
        [-grid.side_m + (cols + 0.5) * grid.cell_m, -grid.back_m + (rows + 0.5) * grid.cell_m]
    )
    rock = world_to_vehicle_xy(_at(terrain, ROCK_STATION_M, ROCK_LATERAL_M), (pose.x, pose.y), pose.yaw)[0]
    # every cell within the 2 m band around the 0.6 x 0.8 m rock (half-diagonal 0.5 m), give or take
    # the 0.4 m class raster and the 0.8 m block a false alarm is born in
    assert np.max(np.hypot(*(cells - rock).T)) < 0.5 + 2.0 + 1.0


def test_a_drawn_pit_is_one_blob_on_its_rim_even_beside_the_car():
    """Beside the car a pit spans little range: offsets can move its range band off the rim. The
    PEM still draws it as the detector's hits are, one blob sharing cells with the rim."""
    from scipy import ndimage

    from negobs_gym.envs.pem import channel_outlines, rasterise_outlines
    from negobs_gym.sim.carving import NegativeObstacleSpec

    pit = NegativeObstacleSpec(
        kind="pit", length_m=1.0, width_m=0.5, depth_m=0.5, station_m=10.0, lateral_m=2.8
    )
    terrain = generate_terrain(TerrainConfig(length_m=30.0, negative_obstacles=(pit,)), 0)
    grid = ObservationConfig().grid
    for station, near in ((10.0, 0.6), (10.0, -0.6), (4.0, 0.6), (8.0, 0.0)):
        xy, yaw = terrain.track.pose_at(np.array(station), np.array(0.0))
        pose = Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw))
        model = constant_model(1.0, near=near, far=near)
        layer = PemGrid(model, grid, terrain, np.random.default_rng(0)).layer(pose)
        (_, mask, rows, cols), *_ = rasterise_outlines(
            channel_outlines(terrain, "negative"), pose, grid, np.array([[-1e9, -1e9, 1e9, 1e9]])
        )
        truth = np.zeros(grid.shape, dtype=bool)
        truth[rows, cols] = mask
        _, count = ndimage.label(layer, structure=np.ones((3, 3), dtype=bool))
        assert count == 1, (station, near)
        assert (layer & truth).any(), (station, near)


def test_a_never_drawn_share_is_not_smeared_into_near_first_drawings():
    """First-confirmation quantiles (-1 = never, then 9 m): a pit is first drawn at 9 m or never,
    not at the distances a linear read between the two would give."""
    from negobs_gym.envs.pem import channel_outlines, pit_centre_distance_m, rasterise_outlines
    from negobs_gym.sim.carving import NegativeObstacleSpec

    pit = NegativeObstacleSpec(
        kind="pit", length_m=1.0, width_m=1.0, depth_m=0.5, station_m=25.0, lateral_m=0.0
    )
    terrain = generate_terrain(TerrainConfig(length_m=40.0, negative_obstacles=(pit,)), 0)
    grid = ObservationConfig().grid
    base = constant_model(1.0)
    model = dataclasses.replace(
        base, parameters=dataclasses.replace(base.parameters, confirm_distance_m=((-1.0, 9.0),))
    )
    firsts = []
    for seed in range(30):
        pem = PemGrid(model, grid, terrain, np.random.default_rng(seed))
        first = None
        for station in np.arange(4.0, 24.0, 0.5):
            xy, yaw = terrain.track.pose_at(np.array(station), np.array(0.0))
            pose = Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw))
            if pem.layer(pose).any() and first is None:
                (_, mask, rows, cols), *_ = rasterise_outlines(
                    channel_outlines(terrain, "negative"), pose, grid, np.array([[-1e9, -1e9, 1e9, 1e9]])
                )
                first = pit_centre_distance_m(grid, mask, rows, cols)
        firsts.append(first)
    drawn = [f for f in firsts if f is not None]
    assert 0 < len(drawn) < len(firsts)  # both outcomes occur
    assert all(8.4 <= f <= 9.0 for f in drawn), drawn
