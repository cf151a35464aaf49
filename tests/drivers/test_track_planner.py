"""The track planner: a path around ground-truth obstacles, on the track, that the car drives."""

import numpy as np
import pytest

from negobs_gym.core.geometry import vehicle_to_world_xy
from negobs_gym.drivers import Driver, PurePursuitDriver, TrackPlannerConfig, TrackPlannerDriver
from negobs_gym.drivers.track_planner import ObstacleBands, blocked_moves, planned_lateral_m, track_state
from negobs_gym.envs import make_env
from negobs_gym.errors import ConfigError
from negobs_gym.sim.carving import PositiveObstacleSpec
from negobs_gym.sim.presets import braking_track, trench_crossing
from negobs_gym.sim.terrain import TerrainConfig, generate_terrain, track_coordinates

CONFIG = TrackPlannerConfig()


def _points_lateral(stations, lateral, offsets_m):
    """Lateral offsets (M-1, P) of points ``offsets_m`` ahead of the rear axle, along its heading."""
    slope = np.diff(lateral) / np.diff(stations)
    return lateral[1:, None] + slope[:, None] * offsets_m, stations[1:, None] + offsets_m


def _band(terrain, outline):
    s, lat = track_coordinates(terrain.track, outline)
    return s.min(), s.max(), lat.min(), lat.max()


def test_path_keeps_the_wheels_off_a_ditch_on_the_right_half() -> None:
    # a 3 m wide ditch covering lateral 0..3 m (the track's right half), 20 m ahead
    terrain = braking_track(20.0, ditch_width_m=3.0, lateral_offset_m=1.5, rough=False, length_m=50.0)
    stations, lateral = planned_lateral_m(terrain, CONFIG)
    edge = terrain.track.width_m / 2 - CONFIG.edge_margin_m
    assert lateral[0] == 0.0 and np.all(np.abs(lateral) <= edge + 1e-9)
    s0, s1, l0, _ = _band(terrain, terrain.negative_obstacles[0].outline_xy_m)
    wheels_lat, wheels_s = _points_lateral(stations, lateral, np.array([0.0, CONFIG.wheelbase_m]))
    over = (wheels_s >= s0) & (wheels_s <= s1)
    assert over.any()
    # every wheel over the ditch's stations runs left of it with the clearance kept
    assert np.all(wheels_lat[over] + CONFIG.half_track_m + CONFIG.wheel_clearance_m <= l0 + 1e-9)
    assert abs(lateral[-1]) < 0.5 * np.abs(lateral).max()  # and heads back to the centre line


def test_path_keeps_the_body_off_a_box_on_the_left() -> None:
    box = PositiveObstacleSpec(kind="box", station_m=20.0, lateral_m=-1.0)
    terrain = generate_terrain(TerrainConfig(length_m=50.0, positive_obstacles=(box,)), seed=0)
    stations, lateral = planned_lateral_m(terrain, CONFIG)
    obstacle = terrain.positive_obstacles[0]
    hx, hy = obstacle.half_extents_m[:2]
    corners = np.asarray(obstacle.centre_m[:2]) + np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    s0, s1, _, l1 = _band(terrain, corners)
    body = np.arange(-CONFIG.rear_overhang_m, CONFIG.length_m - CONFIG.rear_overhang_m + 1e-9, 0.25)
    body_lat, body_s = _points_lateral(stations, lateral, body)
    over = (body_s >= s0) & (body_s <= s1)
    assert over.any()
    assert np.all(body_lat[over] - CONFIG.half_width_m - CONFIG.clearance_m >= l1 - 1e-9)


def test_off_the_path_it_plans_again_from_where_the_car_is() -> None:
    # a 1 m pit across the centre line, 20-21 m: room on both sides
    terrain = braking_track(20.0, ditch_width_m=1.0, lateral_offset_m=0.0, rough=False, length_m=50.0)
    _, first = planned_lateral_m(terrain, CONFIG)
    side = np.sign(first[np.argmax(np.abs(first))])  # the side the first path passes on (+ right)
    start = (14.2, -2.0 * side)  # 6 m before the pit, on the other side
    stations, lateral = planned_lateral_m(terrain, CONFIG, start)
    assert stations[0] == 14.0 and lateral[0] == pytest.approx(start[1])
    s0, s1, l0, l1 = _band(terrain, terrain.negative_obstacles[0].outline_xy_m)
    wheels_lat, wheels_s = _points_lateral(stations, lateral, np.array([0.0, CONFIG.wheelbase_m]))
    over = (wheels_s >= s0) & (wheels_s <= s1)
    wheel_widen = CONFIG.half_track_m + CONFIG.wheel_clearance_m
    assert over.any()
    if side < 0:  # the first path went left, the new one passes right of the pit
        assert np.all(wheels_lat[over] - wheel_widen >= l1 - 1e-9)
    else:
        assert np.all(wheels_lat[over] + wheel_widen <= l0 - 1e-9)

    xy, yaw = terrain.track.pose_at(start[0], start[1])
    info = {"pose": np.array([*xy, 0.0, 0.0, 0.0, float(yaw)]), "speed_mps": 4.0}
    replanning = TrackPlannerDriver(terrain)
    fixed = TrackPlannerDriver(terrain, TrackPlannerConfig(replan_deviation_m=0.0))
    towards_old_path = fixed.act(None, info)[1]  # steering, + left
    assert fixed.replans == 0 and towards_old_path == pytest.approx(side * -1.0)  # full lock across the pit
    assert abs(replanning.act(None, info)[1]) < 0.5 and replanning.replans == 1
    replanning.reset()
    assert replanning.replans == 0 and np.array_equal(replanning.route_xy_m, fixed.route_xy_m)


def test_with_a_sight_limit_it_plans_around_an_obstacle_once_it_comes_into_sight() -> None:
    # a 3 m wide ditch on the track's right half at 20-23 m
    terrain = braking_track(20.0, ditch_width_m=3.0, lateral_offset_m=1.5, rough=False, length_m=50.0)
    _, blind = planned_lateral_m(terrain, CONFIG, sight_until_m=19.0)
    _, seen = planned_lateral_m(terrain, CONFIG, sight_until_m=20.5)
    assert np.all(blind == 0.0)  # nothing in sight: the centre line
    assert seen.min() < -1.0  # the ditch begins at 20 m: the path passes left of it

    config = TrackPlannerConfig(sight_m=10.0)
    driver = TrackPlannerDriver(terrain, config)
    assert np.all(driver.path_m[1] == 0.0) and driver.replans == 0

    def at(station_m: float) -> dict:
        xy, yaw = terrain.track.pose_at(station_m, 0.0)
        return {"pose": np.array([*xy, 0.0, 0.0, 0.0, float(yaw)]), "speed_mps": 4.0}

    driver.act(None, at(9.0))
    assert driver.replans == 0  # the ditch is 11 m ahead
    driver.act(None, at(10.6))
    assert driver.replans == 1 and driver.path_m[1].min() < -1.0
    driver.act(None, at(11.0))
    assert driver.replans == 1  # no new obstacle, still on the path
    driver.reset()
    assert driver.replans == 0 and np.all(driver.path_m[1] == 0.0)
    # without a limit the first path already passes the ditch
    assert planned_lateral_m(terrain, CONFIG)[1].min() < -1.0


def test_a_course_without_a_free_path_still_gets_a_path_on_the_track() -> None:
    terrain = trench_crossing(20.0, rough=False)  # the trench spans the track: no way around
    stations, lateral = planned_lateral_m(terrain, CONFIG)
    assert stations.shape == lateral.shape and np.all(np.isfinite(lateral))
    assert np.all(np.abs(lateral) <= terrain.track.width_m / 2 - CONFIG.edge_margin_m + 1e-9)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("half_width_m", 0.0),
        ("max_slope", float("nan")),
        ("clearance_m", -0.1),
        ("rear_overhang_m", 5.0),
        ("replan_deviation_m", -0.1),
        ("sight_m", float("inf")),
        ("plan_horizon_m", -1.0),
        ("bend_steps", -1),
        ("bend_steps", 1.0),
        ("bend_steps", True),
    ],
)
def test_config_rejects_bad_values(field, value) -> None:
    with pytest.raises(ConfigError, match=field):
        TrackPlannerConfig(**{field: value})


def _drive(env, driver_for, seed):
    obs, info = env.reset(seed=seed)
    driver = driver_for(env.unwrapped.terrain)
    while True:
        obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
        if terminated or truncated:
            return info


def test_it_reaches_the_goal_of_an_offroad_nav_v2_course_where_pure_pursuit_enters_a_pit() -> None:
    env = make_env("negobs_gym/OffroadTrack-v0", ["observation.source=oracle"])
    try:
        planner = _drive(env, TrackPlannerDriver, 1_000_000)
        pursuit = _drive(env, lambda t: PurePursuitDriver(t.track.centreline_xy_m), 1_000_000)
    finally:
        env.close()
    assert isinstance(TrackPlannerDriver(env.unwrapped.terrain), Driver)
    assert planner["termination"] == ["goal"]
    assert pursuit["termination"] == ["entered_negative_obstacle"] and pursuit["station_m"] < 30.0


def test_obstacle_bands_begin_where_their_obstacles_do_and_filter_by_sight() -> None:
    from negobs_gym.drivers.track_planner import ObstacleBands
    from negobs_gym.sim.presets import winding_course

    terrain = winding_course(120.0, seed=3)
    bands = ObstacleBands.of(terrain, CONFIG)
    outlines = [np.asarray(o.outline_xy_m) for o in terrain.negative_obstacles]
    outlines += [o.footprint_xy_m for o in terrain.positive_obstacles]
    begins = np.sort([_band(terrain, xy)[0] for xy in outlines])
    np.testing.assert_allclose(bands.starts_m(), begins, atol=1e-9)
    assert len(bands.pits) == len(terrain.negative_obstacles) and len(begins) >= 4
    until = float(begins[1])  # the first two obstacles in sight
    seen = bands.seen(until)
    assert len(seen.starts_m()) == 2 and np.all(seen.starts_m() <= until)
    # precomputed bands plan as the terrain's own
    for sight in (until, np.inf):
        expected = planned_lateral_m(terrain, CONFIG, (4.0, 0.5), sight)
        np.testing.assert_array_equal(
            planned_lateral_m(terrain, CONFIG, (4.0, 0.5), sight, bands)[1], expected[1]
        )


def test_planning_at_every_step_makes_the_label_a_function_of_where_the_car_is() -> None:
    # a 1 m pit across the centre line, 20-21 m: room on both sides
    terrain = braking_track(20.0, ditch_width_m=1.0, lateral_offset_m=0.0, rough=False, length_m=50.0)
    stations, lateral = planned_lateral_m(terrain, CONFIG, (3.3, 0.0), horizon_m=12.0)
    assert stations[0] == 3.0 and stations[-1] == pytest.approx(15.0) and lateral.shape == stations.shape
    for beyond in (terrain.track.length_m, terrain.track.length_m + 3.0):  # a car past the end
        assert len(planned_lateral_m(terrain, CONFIG, (beyond, 0.0), horizon_m=12.0)[0]) == 2

    def at(station_m: float, lateral_m: float) -> dict:
        xy, yaw = terrain.track.pose_at(station_m, lateral_m)
        return {"pose": np.array([*xy, 0.0, 0.0, 0.0, float(yaw)]), "speed_mps": 4.0}

    here = at(15.0, 0.3)
    # two histories: one car came along the centre line, the other from 1.2 m left of it
    for config in (
        TrackPlannerConfig(plan_horizon_m=20.0),
        TrackPlannerConfig(sight_m=14.0, plan_horizon_m=20.0),
    ):
        along, beside, fresh = (TrackPlannerDriver(terrain, config) for _ in range(3))
        for station in (5.0, 10.0):
            along.act(None, at(station, 0.0))
            beside.act(None, at(station, -1.2))
        actions = [driver.act(None, here) for driver in (along, beside, fresh)]
        np.testing.assert_array_equal(actions[0], actions[1])
        np.testing.assert_array_equal(actions[0], actions[2])
        assert fresh.replans == 1 and along.replans == 3
    # the default planner keeps the path it planned from where it was: its label remembers
    along, beside = TrackPlannerDriver(terrain), TrackPlannerDriver(terrain)
    along.act(None, at(5.0, 0.0))
    beside.act(None, at(5.0, -1.2))  # 1.2 m off its first path: it plans again from here
    assert beside.replans == 1 and along.replans == 0
    assert not np.array_equal(along.path_m[1], beside.path_m[1])


def test_blocked_moves_counts_the_moves_a_path_puts_in_a_band() -> None:
    # a 1 m pit across the centre line at 20-21 m: the planned path is free of it, the centre line
    # is not, and a path whose axles pass just beside the pit's band is free too
    terrain = braking_track(20.0, ditch_width_m=1.0, lateral_offset_m=0.0, rough=False, length_m=50.0)
    bands = ObstacleBands.of(terrain, CONFIG)
    stations, lateral = planned_lateral_m(terrain, CONFIG)
    assert blocked_moves(stations, lateral, bands, CONFIG) == 0
    straight = np.zeros_like(stations)
    s0, s1 = bands.pits[0, :2]
    # a move counts when either axle (rear, front at the wheelbase) lies within the pit's stations
    axles_s = stations[1:, None] + np.array([0.0, CONFIG.wheelbase_m])
    expected = int(np.sum(np.any((axles_s >= s0) & (axles_s <= s1), axis=1)))
    assert blocked_moves(stations, straight, bands, CONFIG) == expected > 0
    beside = np.full_like(stations, bands.pits[0, 3] + 0.05)  # the rear axle's centre just outside
    assert blocked_moves(stations, beside, bands, CONFIG) == 0
    # a move in a body band and a pit band at once counts once
    both = ObstacleBands(bodies=bands.pits, pits=bands.pits, mounds=bands.mounds, lead_m=bands.lead_m)
    body_s = stations[1:, None] + np.arange(
        -CONFIG.rear_overhang_m, CONFIG.length_m - CONFIG.rear_overhang_m + 1e-9, 0.25
    )
    either = np.any((body_s >= s0) & (body_s <= s1), axis=1) | np.any(
        (axles_s >= s0) & (axles_s <= s1), axis=1
    )
    assert blocked_moves(stations, straight, both, CONFIG) == int(np.sum(either)) > expected


def test_blocked_moves_refuses_paths_it_cannot_read() -> None:
    bands = ObstacleBands.of(braking_track(20.0, rough=False, length_m=50.0), CONFIG)
    with pytest.raises(ValueError, match="one length"):
        blocked_moves(np.arange(4.0), np.zeros(3), bands, CONFIG)
    with pytest.raises(ValueError, match="increase"):
        blocked_moves(np.array([0.0, 1.0, 1.0]), np.zeros(3), bands, CONFIG)


HEADING = TrackPlannerConfig(bend_steps=1)


def test_heading_lattice_starts_along_the_cars_heading_and_bends_gradually() -> None:
    terrain = braking_track(40.0, ditch_width_m=1.0, rough=False, length_m=60.0)
    # the car points 0.6 m sideways per metre to the right: the lattice's nearest move is 0.3 m
    # per 0.5 m station, and every move, the first included, differs from the one before by at
    # most one 0.1 m step
    _, lateral = planned_lateral_m(terrain, HEADING, (0.0, 0.0), horizon_m=20.0, start_slope=0.6)
    steps = np.round(np.diff(lateral) / HEADING.lateral_step_m).astype(int)
    assert steps[0] == 2 and steps[1] == 1 and np.all(steps[2:] == 0)  # straightened out, 0.3 m right
    assert np.all(np.abs(np.diff(steps)) <= HEADING.bend_steps)
    # the offset lattice ignores the heading: it stays on the centre line
    assert np.all(planned_lateral_m(terrain, CONFIG, (0.0, 0.0), horizon_m=20.0, start_slope=0.6)[1] == 0)


@pytest.mark.parametrize("bend_steps", [0, 1, 2])
def test_heading_lattice_keeps_its_paths_free_of_the_obstacles(bend_steps) -> None:
    config = TrackPlannerConfig(bend_steps=bend_steps)
    for terrain in (
        braking_track(20.0, ditch_width_m=3.0, lateral_offset_m=1.5, rough=False, length_m=50.0),
        braking_track(20.0, ditch_width_m=1.0, lateral_offset_m=0.0, rough=False, length_m=50.0),
    ):
        bands = ObstacleBands.of(terrain, config)
        stations, lateral = planned_lateral_m(terrain, config, bands=bands)
        assert lateral[0] == 0.0 and blocked_moves(stations, lateral, bands, config) == 0
        if bend_steps:
            steps = np.round(np.diff(lateral) / config.lateral_step_m).astype(int)
            assert np.all(np.abs(np.diff(steps)) <= bend_steps)


def test_track_state_gives_the_cars_place_and_heading_on_the_track() -> None:
    terrain = generate_terrain(TerrainConfig(length_m=60.0), seed=3)
    track = terrain.track
    xy, yaw = track.pose_at(np.array([25.0]), 0.5)
    # 0.3 m sideways per metre of station, to the right: turned by atan(0.3) clockwise
    pose = np.array([xy[0, 0], xy[0, 1], 0.0, 0.0, 0.0, yaw[0] - np.arctan(0.3)])
    station, lateral, slope = track_state(track, pose)
    assert station == pytest.approx(25.0, abs=0.01) and lateral == pytest.approx(0.5, abs=0.01)
    assert slope == pytest.approx(0.3, abs=0.02)
    ahead = vehicle_to_world_xy(np.array([[0.0, 1.0]]), pose[:2], float(pose[5]))
    assert track_coordinates(track, ahead)[1][0] > lateral  # + right, as the lateral offset
    for bad in (pose[:3], np.where(np.arange(6) == 5, np.nan, pose)):
        with pytest.raises(ValueError, match="pose: must be 6 finite numbers"):
            track_state(track, bad)


def test_track_planner_driver_on_the_heading_lattice_reaches_an_offroad_nav_v2_goal() -> None:
    env = make_env("offroad_nav_v2", ["observation.source=oracle"])
    config = TrackPlannerConfig(bend_steps=1, plan_horizon_m=20.0)
    try:
        info = _drive(env, lambda terrain: TrackPlannerDriver(terrain, config), 1_000_001)
    finally:
        env.close()
    assert info["termination"] == ["goal"]
