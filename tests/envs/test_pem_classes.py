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
    outline_distance_m,
    terrain_classes,
)
from negobs_gym.sim.carving import PositiveObstacleSpec
from negobs_gym.sim.terrain import BorderConfig, TerrainConfig, generate_terrain
from negobs_gym.spec import ObservationConfig
from tests.envs.test_pem_model import constant_model, constant_parameters

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
    # beyond the raster, just before its first cell, and NaN: smooth ground
    (x0, y0), ny, nx = raster.origin_m, *raster.classes.shape
    outside = np.array([[x0 - 1e-9, y0 + 1.0], [x0 + 1.0, y0 + ny * raster.resolution_m], [np.nan, y0 + 1.0]])
    assert raster.at(outside).tolist() == [TERRAIN_CLASSES.index("smooth")] * 3
    corner = np.array([[x0 + 1e-9, y0 + 1e-9], [x0 + (nx - 1e-6) * raster.resolution_m, y0]])
    assert raster.at(corner).tolist() == [raster.classes[0, 0], raster.classes[0, -1]]


def test_outline_distance_is_zero_inside_the_edge_distance_beside_and_inf_beyond_reach():
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    far_square = square + 10.0
    points = np.array([[1.0, 0.5], [2.5, 0.5], [1.0, -0.3], [3.0, 2.0], [5.0, 0.5]])
    d = outline_distance_m(points, [square, far_square], 2.0)
    assert d[:3] == pytest.approx([0.0, 0.5, 0.3])
    assert d[3] == pytest.approx(np.hypot(1.0, 1.0))
    assert d[4] == np.inf  # 3 m from the nearest edge, beyond the 2 m reach
    assert outline_distance_m(points, [], 2.0).tolist() == [np.inf] * 5


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
    # the pit comes onto the grid ~21 m out: beyond approach_m, so its first drawing is by distance
    confirm = dataclasses.replace(base.parameters, confirm_distance_m=((-1.0, 9.0),), approach_m=15.0)
    model = dataclasses.replace(base, parameters=confirm)
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


def _drive(model, terrain, channel, stations, seed=0, obstacle=0):
    """The PEM's layers along the centre line at ``stations`` [m], with the truth of the channel's
    ``obstacle`` (the rock of :func:`terrain`'s positive ones)."""
    from negobs_gym.envs.pem import channel_outlines, outline_boxes, rasterise_outlines

    grid = ObservationConfig().grid
    pem = PemGrid(model, grid, terrain, np.random.default_rng(seed), channel=channel)
    outlines = channel_outlines(terrain, channel)[obstacle : obstacle + 1]
    out = []
    for station in stations:
        xy, yaw = terrain.track.pose_at(np.array(station), np.array(0.0))
        pose = Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw))
        truth = np.zeros(grid.shape, dtype=bool)
        for _, mask, rows, cols in rasterise_outlines(outlines, pose, grid, outline_boxes(outlines)):
            truth[rows, cols] |= mask
        out.append((pem.layer(pose), truth))
    return out


def test_an_obstacle_nearer_than_its_loss_distance_is_never_drawn_again(terrain):
    """Loss distance 6 m on the positive channel: the rock (15 m down the track) is drawn on the
    approach until it is 6 m away, then never, though the chain would keep it (p = 1)."""
    base = constant_model(1.0, positive=1.0)
    lossy = dataclasses.replace(base.positive, loss_distance_m=((6.0, 6.0),))
    model = dataclasses.replace(base, positive=lossy)
    stations = np.arange(0.0, 14.0, 0.5)
    frames = _drive(model, terrain, "positive", stations)
    distance = np.hypot(ROCK_STATION_M - stations, ROCK_LATERAL_M)
    drawn = np.array([(layer & truth).any() for layer, truth in frames])
    seen = np.array([truth.any() for _, truth in frames])
    assert drawn[seen & (distance > 6.3)].all()
    assert not drawn[distance < 5.7].any()
    plain = _drive(base, terrain, "positive", stations)  # without a loss table: drawn to the end
    assert all((layer & truth).any() for layer, truth in plain if truth.any())


def test_an_obstacle_first_seen_within_reach_waits_its_latency_and_its_loss_holds(terrain):
    """The episode starts ~11 m from the rock (within approach_m): it is drawn after the latency
    (3 frames); a "never" confirmation holds, and so does a loss distance beyond where it stands
    (the LUX's layers already pass over it; one coming from afar would be drawn once)."""
    base = constant_model(1.0, positive=1.0)
    params = dataclasses.replace(base.positive, confirm_latency_frames=(3.0, 3.0))
    stations = np.full(6, 5.0)
    frames = _drive(dataclasses.replace(base, positive=params), terrain, "positive", stations)
    assert [bool((layer & truth).any()) for layer, truth in frames] == [False] * 3 + [True] * 3
    for changed in ({"confirm_distance_m": ((-1.0, -1.0),)}, {"loss_distance_m": ((12.0, 12.0),)}):
        model = dataclasses.replace(base, positive=dataclasses.replace(params, **changed))
        assert not any((layer & truth).any() for layer, truth in _drive(model, terrain, "positive", stations))


def test_false_alarms_keep_clear_of_the_obstacles_by_the_fits_match_cells(terrain):
    """Clutter false alarms dense around the rock, the rock itself never drawn: none of them lands
    within match_cells (2) of the rock's cells, where the judge would count it as the rock drawn."""
    base = constant_model(0.0, positive=0.0)
    density = np.zeros((len(TERRAIN_CLASSES), 2))
    density[TERRAIN_CLASSES.index("clutter")] = 2.0
    blob = (float(TERRAIN_CLASSES.index("clutter")), 0.0, 1.0, 1.0, 1.0, 1.0)
    dense = dataclasses.replace(base.positive, fa_density_per_m2=tuple(map(tuple, density)), fa_blobs=(blob,))
    for cells, touching in ((2, False), (0, True)):
        model = dataclasses.replace(base, positive=dataclasses.replace(dense, match_cells=cells))
        frames = _drive(model, terrain, "positive", np.arange(5.0, 9.0, 0.5))
        from scipy import ndimage

        near = [layer & ndimage.binary_dilation(truth, iterations=2) for layer, truth in frames]
        assert sum(layer.sum() for layer, _ in frames) > 0
        assert any(n.any() for n in near) == touching


def test_an_obstacle_is_sized_by_its_whole_outline_in_cells_without_float_error():
    """A box's 1 x 1 m footprint is 25 cells (the fit's rasterised count), not 24.999...: with the
    tables' sizes split at 25 cells, it takes the row of 25 and up (drawn), not the one below (never)."""
    box = PositiveObstacleSpec(kind="box", station_m=15.0, lateral_m=2.0)
    terrain = generate_terrain(TerrainConfig(length_m=30.0, positive_obstacles=(box,)), 0)
    base = constant_model(1.0, positive=1.0)
    split = dataclasses.replace(
        base.positive,
        size_edges_cells=(0.0, 25.0, 10_000.0),
        confirm_distance_m=((-1.0, -1.0), (100.0, 100.0)),
        p_keep=((1.0, 1.0), (1.0, 1.0)),
        p_return=((1.0, 1.0), (1.0, 1.0)),
        sightings=((1, 1), (1, 1)),
    )
    frames = _drive(dataclasses.replace(base, positive=split), terrain, "positive", np.arange(0.0, 8.0, 0.5))
    assert frames[0][1].sum() == 25
    assert all((layer & truth).any() for layer, truth in frames)


def test_ground_coming_into_view_starts_with_the_mean_false_alarm_population(terrain):
    """0.02 false alarms per m² on every class, each surviving a frame with p 0.9: the band the
    car's advance (0.5 m a frame) brings into view holds the mean from its first frame on (with
    births at 1 - 0.9 of it alone, the 2 m band at the grid's far edge would hold a quarter)."""
    base = constant_model(0.0)
    density = tuple((0.02, 0.02) for _ in TERRAIN_CLASSES)
    params = dataclasses.replace(
        base.parameters, fa_density_per_m2=density, fa_keep=((0.9, 0.9),) * len(TERRAIN_CLASSES)
    )
    model = dataclasses.replace(base, parameters=params)
    grid = ObservationConfig().grid
    band = slice(grid.rows - round(2.0 / grid.cell_m), grid.rows)  # the far 2 m, across the grid
    counts = []
    for seed in range(4):
        frames = _drive(model, terrain, "negative", np.arange(0.0, 4.0, 0.5), seed=seed)
        counts += [layer[band].sum() / 4.0 for layer, _ in frames[1:]]  # 2 x 2-cell blobs
    expected = 0.02 * 2.0 * (2 * grid.side_m)
    assert np.mean(counts) == pytest.approx(expected, rel=0.35)


def _near_edge_offset_m(parameters) -> float:
    """The drawn near edge minus the true one [m] of a 1 m x 1 m pit (25 cells) 10 m ahead."""
    from negobs_gym.envs.pem import PerceptionErrorModel, channel_outlines, pem_settings, rasterise_outlines
    from negobs_gym.sim.carving import NegativeObstacleSpec

    pit = NegativeObstacleSpec(
        kind="pit", length_m=1.0, width_m=1.0, depth_m=0.5, station_m=12.0, lateral_m=0.0
    )
    terrain = generate_terrain(TerrainConfig(length_m=30.0, negative_obstacles=(pit,)), 0)
    grid = ObservationConfig().grid
    xy, yaw = terrain.track.pose_at(np.array(2.0), np.array(0.0))
    pose = Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw))
    (_, mask, rows, cols), *_ = rasterise_outlines(
        channel_outlines(terrain, "negative"), pose, grid, np.array([[-1e9, -1e9, 1e9, 1e9]])
    )
    truth = np.zeros(grid.shape, dtype=bool)
    truth[rows, cols] = mask
    model = PerceptionErrorModel(
        parameters=parameters, fitted_on=pem_settings(ObservationConfig(), ("negative",))
    )
    pem = PemGrid(model, grid, terrain, np.random.default_rng(0))
    layer = pem.layer(pose)
    range_m = np.hypot(*grid.cell_centres().transpose(2, 0, 1))
    return float(range_m[layer].min() - range_m[truth].min())


def test_a_pit_beside_the_car_keeps_the_outline_it_was_drawn_with_from_afar():
    """Edge offsets lie along the view a pit was first drawn from (the detector's fusion keeps its
    cells in the world): a 1 m pit 2 m right of the path, near offset -0.4 m, is drawn 0.4 m long
    in front from 12 m out, and beside the car its inner side stays on the rim, where an offset
    measured from the car's place would move it 0.4 m towards the car."""
    from negobs_gym.envs.pem import PerceptionErrorModel, channel_outlines, pem_settings, rasterise_outlines
    from negobs_gym.sim.carving import NegativeObstacleSpec

    pit = NegativeObstacleSpec(
        kind="pit", length_m=1.0, width_m=1.0, depth_m=0.5, station_m=16.0, lateral_m=2.0
    )
    terrain = generate_terrain(TerrainConfig(length_m=40.0, negative_obstacles=(pit,)), 0)
    grid = ObservationConfig().grid
    model = PerceptionErrorModel(
        parameters=constant_parameters(1.0, near=-0.4),
        fitted_on=pem_settings(ObservationConfig(), ("negative",)),
    )
    pem = PemGrid(model, grid, terrain, np.random.default_rng(0))
    x, y = grid.cell_centres().transpose(2, 0, 1)
    outlines = channel_outlines(terrain, "negative")
    seen = []
    for station in np.arange(4.0, 15.01, 0.5):  # from 12 m before the pit to beside the car's front
        xy, yaw = terrain.track.pose_at(np.array(station), np.array(0.0))
        pose = Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw))
        (_, mask, rows, cols), *_ = rasterise_outlines(
            outlines, pose, grid, np.array([[-1e9, -1e9, 1e9, 1e9]])
        )
        truth = np.zeros(grid.shape, dtype=bool)
        truth[rows, cols] = mask
        seen.append((pem.layer(pose), truth))
    far_layer, far_truth = seen[0]
    assert y[far_layer].min() - y[far_truth].min() == pytest.approx(-0.4, abs=0.11)  # longer in front
    far_inner = np.abs(x[far_layer]).min()  # a cell beside the rim: the span's slack
    assert far_inner - np.abs(x[far_truth]).min() == pytest.approx(-grid.cell_m)
    for layer, _ in seen:
        assert np.abs(x[layer]).min() == far_inner  # not 0.4 m nearer the car as it comes alongside
    assert y[seen[-1][1]].min() < 1.0  # the last pose: the pit lies beside the car's front


def test_a_drawn_near_edge_is_the_cell_range_nearest_the_drawn_offset():
    """The fit measures the detector's near edge between cell centres; the PEM rounds a drawn offset
    to the nearest cell, so one of -0.15 m draws the row in front and one of -0.05 m does not."""
    cell = ObservationConfig().grid.cell_m
    offsets = {
        near: _near_edge_offset_m(constant_parameters(1.0, near=near)) for near in (-0.15, -0.05, 0.0, 0.35)
    }
    assert offsets[-0.15] == pytest.approx(-cell, abs=0.05)  # the row in front
    assert offsets[-0.05] == pytest.approx(0.0, abs=0.05) and offsets[0.0] == pytest.approx(0.0, abs=1e-9)
    assert offsets[0.35] == pytest.approx(2 * cell, abs=0.05)  # two rows behind, not 0.35's floor


def test_edge_offsets_are_drawn_from_the_obstacles_size_bin():
    """Per-size tables: the 25-cell pit draws its own size bin's offset, not another's."""
    base = constant_parameters(1.0)
    row = lambda v: ((v, v), (v, v))  # noqa: E731 - two distance bins of two quantiles
    for small, large, expected in ((0.4, -0.2, -0.2), (-0.2, 0.4, 0.4)):
        parameters = dataclasses.replace(
            base,
            size_edges_cells=(0.0, 10.0, 10_000.0),
            confirm_distance_m=base.confirm_distance_m * 2,
            p_keep=base.p_keep * 2,
            p_return=base.p_return * 2,
            sightings=base.sightings * 2,
            near_offset_m=(row(small), row(large)),
            far_offset_m=(row(0.0), row(0.0)),
        )
        assert _near_edge_offset_m(parameters) == pytest.approx(expected, abs=0.05)
