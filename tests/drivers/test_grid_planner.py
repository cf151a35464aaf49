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
from negobs_gym.eval.episode import STANDSTILL_S, EpisodeStop, drive_episode
from negobs_gym.eval.scenario_runner import make_driver as eval_driver
from negobs_gym.safety import SafetyFilterConfig, braking_distance_m, hazard_distance_m
from negobs_gym.sim.presets import braking_track
from negobs_gym.sim.vehicle import VehicleConfig
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


def _passes_with_lead(action: np.ndarray, grid: np.ndarray, speed: float, lead_s: float) -> bool:
    """Eq. 18 with ``lead_s`` to spare, worked out here from the corridor and R(v), on the grid's
    negative cells, for the envs' car at the default filter and 10 Hz."""
    car, rules = VehicleConfig(), SafetyFilterConfig()
    points = observed_cells(OBSERVATION).centres_of(grid[OBSERVATION.channels.index("negative")] > 0)
    d = hazard_distance_m(
        points,
        float(action[1]) * car.max_steer_rad,
        car.wheelbase_m,
        0.5 * (car.width_m + rules.margin_m),
        car.length_m - car.rear_overhang_m,
    )
    accel = action[0] * (car.max_accel_mps2 if action[0] >= 0 else car.tyre_mu * 9.81)
    v_next = max(0.0, speed + 0.1 * accel)
    travelled = 0.05 * (speed + v_next)
    return bool(d - travelled >= braking_distance_m(v_next) + v_next * lead_s)


def test_with_filter_lead_s_its_steering_keeps_to_arcs_that_pass_eq18_with_the_lead() -> None:
    rng = np.random.default_rng(7)
    branches = {"kept": 0, "moved": 0, "left to the filter": 0}
    for _ in range(60):
        # a 2.4 x 1.6 m pit 5-12 m ahead in the car's frame, the car up to 23 deg off the track
        x0, y0 = rng.uniform(-3.0, 2.0), rng.uniform(5.0, 12.0)
        pit = {"negative": [(x, y) for x in x0 + np.arange(3) * 0.8 for y in y0 + np.arange(2) * 0.8]}
        pose = POSE.copy()
        pose[5] = rng.uniform(-0.4, 0.4)
        obs, info = {"grid": _grid(pit)}, {"pose": pose, "speed_mps": float(rng.uniform(1.0, 5.0))}
        plain = GridPlannerDriver(TERRAIN, OBSERVATION).act(obs, info)
        within = GridPlannerDriver(TERRAIN, OBSERVATION, GridPlannerConfig(filter_lead_s=1.0)).act(obs, info)
        assert within[0] == plain[0]  # it steers only
        if _passes_with_lead(plain, obs["grid"], info["speed_mps"], 1.0):
            np.testing.assert_array_equal(within, plain)
            branches["kept"] += 1
        elif _passes_with_lead(within, obs["grid"], info["speed_mps"], 1.0):
            branches["moved"] += 1
        else:  # no steering passes: its own is left to the filter
            np.testing.assert_array_equal(within, plain)
            assert not any(
                _passes_with_lead(np.array([plain[0], s]), obs["grid"], info["speed_mps"], 1.0)
                for s in np.arange(-1.0, 1.0001, 0.05)
            )
            branches["left to the filter"] += 1
    assert branches["moved"] >= 3 and branches["kept"] >= 10, branches


def test_filter_lead_s_must_be_finite_and_not_negative() -> None:
    for bad in (-0.5, np.nan):
        with pytest.raises(ConfigError, match="filter_lead_s"):
            GridPlannerConfig(filter_lead_s=bad)
    with pytest.raises(ConfigError, match="control_period_s"):
        GridPlannerDriver(TERRAIN, OBSERVATION, control_period_s=0.0)


# slow (end to end, two drives on the detector grid, ~1 min): the choice itself is checked above
@pytest.mark.slow
def test_keeping_to_the_filters_arcs_it_passes_the_pit_it_stood_before_behind_the_filter() -> None:
    """OffroadNav-v2 seed 1,000,000 at 0.2 m cells, 15 km/h, behind the brake-only filter: the
    heading lattice swerves to a gap with full lock, whose arc meets the drawn pit inside R(v), and
    the car stands before it; asking Eq. 18 first, it steers an arc that passes and goes on."""
    settings = [
        "observation.source=detector",
        "observation.downsample=1",
        "run.target_speed_mps=4.17",
        "filter.margin_m=0",
        "filter.hazard_memory_hold_m=8",
        "run.driver_settings.planner.bend_steps=1",
    ]
    ends = {}
    for lead_s in (0.0, 1.0):
        env = make_env("offroad_nav_v2", [*settings, f"run.driver_settings.filter_lead_s={lead_s}"])
        spec = env.unwrapped.scenario
        try:
            ends[lead_s] = drive_episode(
                env,
                lambda e: eval_driver("grid_planner", spec, e.terrain),  # noqa: B023 (used at once)
                seed=1_000_000,
                filter=True,
                stop=EpisodeStop(standstill_s=STANDSTILL_S),
            )
        finally:
            env.close()
    assert ends[0.0].stopped and not ends[0.0].goal_reached and ends[0.0].vetoes > 0
    assert ends[1.0].goal_reached and not ends[1.0].entered_negative_obstacle
    assert ends[1.0].vetoes < ends[0.0].vetoes
