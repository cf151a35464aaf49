"""The grid planner: the track planner's lattice around the obstacles the grid observation shows."""

import dataclasses

import numpy as np
import pytest

from negobs_gym.core.geometry import world_to_vehicle_xy
from negobs_gym.drivers import Driver, GridPlannerConfig, GridPlannerDriver, PurePursuitDriver, make_driver
from negobs_gym.drivers.grid_planner import grid_bands, observed_cells
from negobs_gym.drivers.track_planner import blocked_moves
from negobs_gym.envs import make_env
from negobs_gym.errors import ActionError, ConfigError
from negobs_gym.sim.presets import braking_track
from negobs_gym.spec.observation import ObservationConfig

OBSERVATION = ObservationConfig(channels=("negative", "positive"))  # 0.8 m cells, 36 x 16
CONFIG = GridPlannerConfig()
TERRAIN = braking_track(20.0, rough=False, length_m=60.0)  # straight: station = y, lateral = x
POSE = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # the start, facing the track


def _grid(cells: dict[str, list[tuple[float, float]]], pose: np.ndarray = POSE) -> np.ndarray:
    """A grid with the cells under world points (x, y) set, per channel."""
    spec = observed_cells(OBSERVATION)
    grid = np.zeros((2, *spec.shape), dtype=np.uint8)
    for channel, points in cells.items():
        xy = world_to_vehicle_xy(np.array(points, dtype=float), pose[:2], pose[5])
        row, col, inside = spec.cell_of(xy)
        assert inside.all()
        grid[OBSERVATION.channels.index(channel), row, col] = 1
    return grid


def test_blobs_become_bands_of_their_cells_centres_widened_for_the_car() -> None:
    # a pit of 2 x 2 cells right of the centre line 10 m ahead, a one-cell rock left at 15 m,
    # and a 4 x 3 m rise across the centre at 20 m
    pit = [(x, y) for x in (0.5, 1.3) for y in (10.1, 10.9)]
    rise = [(x, y) for x in (-1.1, -0.3, 0.5, 1.3) for y in (19.7, 20.5, 21.3, 22.1, 22.9)]
    bands = grid_bands(
        _grid({"negative": pit, "positive": [(-1.5, 15.3), *rise]}), POSE, TERRAIN, OBSERVATION, CONFIG
    )
    planner = CONFIG.planner
    wheel = planner.half_track_m + planner.wheel_clearance_m
    # cells are 0.8 m, counted from the grid's edges at x = -6.4 m and y = -3.2 m
    np.testing.assert_allclose(
        bands.pits, [[10.0 - planner.lead_m, 10.8, 0.4 - wheel, 1.2 + wheel]], atol=0.05
    )
    body = planner.half_width_m + planner.clearance_m
    np.testing.assert_allclose(
        bands.bodies, [[15.6 - planner.lead_m, 15.6, -1.2 - body, -1.2 + body]], atol=0.05
    )
    assert bands.mounds.shape == (1, 4) and bands.mounds[0, 1] - bands.mounds[0, 0] > CONFIG.mound_span_m


def test_a_grid_of_the_wrong_shape_or_no_layout_is_refused() -> None:
    with pytest.raises(ActionError, match=r"grid observation: must have shape \(2, 36, 16\)"):
        grid_bands(np.zeros((2, 72, 32), dtype=np.uint8), POSE, TERRAIN, OBSERVATION, CONFIG)
    driver = GridPlannerDriver(TERRAIN, OBSERVATION)
    with pytest.raises(ActionError, match="grid observation"):
        driver.act({"grid": np.zeros((4, 36, 16))}, {"pose": POSE, "speed_mps": 0.0})
    with pytest.raises(ConfigError, match="observation"):
        make_driver("grid_planner", TERRAIN)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("memory_steps", -1),
        ("memory_steps", 1.5),
        ("mound_span_m", np.nan),
        ("pad_m", -0.1),
    ],
)
def test_config_rejects_bad_values(field, value) -> None:
    with pytest.raises(ConfigError, match=field):
        GridPlannerConfig(**{field: value})


def test_it_steers_around_a_pit_on_the_centre_line_and_remembers_it_once_out_of_sight() -> None:
    info = {"pose": POSE, "speed_mps": 4.0}
    pit = {"negative": [(x, y) for x in (-0.3, 0.5) for y in (6.1, 6.9)]}
    remembering = GridPlannerDriver(TERRAIN, OBSERVATION)
    forgetting = GridPlannerDriver(TERRAIN, OBSERVATION, GridPlannerConfig(memory_steps=0))
    for driver in (remembering, forgetting):
        assert isinstance(driver, Driver)
        assert abs(driver.act({"grid": _grid(pit)}, info)[1]) > 0.1  # steers off the centre line
        assert np.abs(driver.path_m[1]).max() > 1.0
        # what it planned around: the pit's band, which its path keeps out of
        assert len(driver.bands.pits) == 1 and len(driver.bands.bodies) == 0
        stations, _ = driver.path_m
        assert blocked_moves(*driver.path_m, driver.bands, driver.config.planner) == 0
        assert blocked_moves(stations, np.zeros_like(stations), driver.bands, driver.config.planner) > 0
    # the pit is gone from the next grid (lost up close): only the memory still passes it
    empty = {"grid": _grid({})}
    remembering.act(empty, info)
    forgetting.act(empty, info)
    assert np.abs(remembering.path_m[1]).max() > 1.0
    assert np.abs(forgetting.path_m[1]).max() == 0.0
    remembering.reset()
    remembering.act(empty, info)
    assert np.abs(remembering.path_m[1]).max() == 0.0


def _drive(env, driver_for, seed):
    obs, info = env.reset(seed=seed)
    driver = driver_for(env.unwrapped)
    while True:
        obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
        if terminated or truncated:
            return info


def test_on_the_oracle_grid_it_reaches_an_offroad_nav_v2_goal_that_pure_pursuit_misses() -> None:
    env = make_env("negobs_gym/OffroadTrack-v0", ["observation.source=oracle", "observation.downsample=2"])
    try:
        planner = _drive(
            env,
            lambda e: make_driver("grid_planner", e.terrain, observation=e.scenario.observation),
            1_000_001,
        )
        pursuit = _drive(env, lambda e: PurePursuitDriver(e.terrain.track.centreline_xy_m), 1_000_001)
    finally:
        env.close()
    assert planner["termination"] == ["goal"]
    assert pursuit["termination"] != ["goal"] and pursuit["station_m"] < 60.0


def test_a_body_band_reaches_body_depth_beyond_its_farthest_cell() -> None:
    rock = {"positive": [(-1.5, 15.3)]}
    deep = grid_bands(_grid(rock), POSE, TERRAIN, OBSERVATION, GridPlannerConfig(body_depth_m=1.0))
    flat = grid_bands(_grid(rock), POSE, TERRAIN, OBSERVATION, CONFIG)
    np.testing.assert_allclose(deep.bodies[:, 1] - flat.bodies[:, 1], [1.0])
    np.testing.assert_allclose(deep.bodies[:, [0, 2, 3]], flat.bodies[:, [0, 2, 3]])


def test_without_a_finite_pose_it_raises_pure_pursuits_error() -> None:
    driver = GridPlannerDriver(TERRAIN, OBSERVATION)
    with pytest.raises(ActionError, match="pose"):
        driver.act({"grid": _grid({})}, {"pose": np.full(6, np.nan), "speed_mps": 1.0})
    with pytest.raises(ActionError, match="pose"):
        driver.act({"grid": _grid({})}, {"speed_mps": 1.0})


def test_on_the_heading_lattice_it_plans_from_the_cars_heading() -> None:
    planner = dataclasses.replace(CONFIG.planner, bend_steps=1)
    driver = GridPlannerDriver(TERRAIN, OBSERVATION, GridPlannerConfig(planner=planner))
    # on the straight track, a yaw of -atan(0.4) points the car 0.4 m right per metre (yaw + left)
    turned = POSE.copy()
    turned[5] = -np.arctan(0.4)
    driver.act({"grid": _grid({}, turned)}, {"pose": turned, "speed_mps": 4.0})
    steps = np.round(np.diff(driver.path_m[1]) / planner.lateral_step_m).astype(int)
    assert steps[0] == 1  # the move before it is the heading's 0.2 m per 0.5 m station
    assert np.all(np.abs(np.diff(steps)) <= 1)
    # the offset lattice plans from the car's place alone
    offset = GridPlannerDriver(TERRAIN, OBSERVATION)
    offset.act({"grid": _grid({}, turned)}, {"pose": turned, "speed_mps": 4.0})
    assert np.all(offset.path_m[1] == 0.0)
