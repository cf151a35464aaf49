"""make_driver: every scripted driver by name, at a target speed, pure pursuit in a lane."""

import numpy as np
import pytest

from negobs_gym.drivers import (
    DRIVER_NAMES,
    ConstantSpeedDriver,
    CreepingDriver,
    GridPlannerDriver,
    PurePursuitDriver,
    RecklessDriver,
    TrackPlannerDriver,
    make_driver,
)
from negobs_gym.errors import ConfigError
from negobs_gym.sim.presets import braking_track
from negobs_gym.spec.observation import ObservationConfig

CLASSES = {
    "reckless": RecklessDriver,
    "constant_speed": ConstantSpeedDriver,
    "pure_pursuit": PurePursuitDriver,
    "track_planner": TrackPlannerDriver,
    "creeping": CreepingDriver,
    "grid_planner": GridPlannerDriver,
}


@pytest.fixture(scope="module")
def terrain():
    return braking_track(ditch_distance_m=20.0, seed=0, rough=False)


@pytest.mark.parametrize("name", DRIVER_NAMES)
def test_each_name_builds_its_driver_at_the_target_speed(terrain, name: str) -> None:
    assert set(CLASSES) == set(DRIVER_NAMES)
    observation = ObservationConfig()  # the grid planner's grid layout; the others ignore it
    default = make_driver(name, terrain, observation=observation)
    driver = make_driver(name, terrain, target_speed_mps=3.0, observation=observation)
    assert type(driver) is CLASSES[name]

    def speed_config(d):
        return {
            "track_planner": lambda: d.config.pursuit,
            "grid_planner": lambda: d.config.planner.pursuit,
        }.get(name, lambda: d.config)()

    config, default_config = speed_config(driver), speed_config(default)
    assert config.target_speed_mps == 3.0 != default_config.target_speed_mps


def test_pure_pursuit_follows_the_centre_line_or_a_lane_beside_it(terrain) -> None:
    track = terrain.track
    centre = make_driver("pure_pursuit", terrain).route_xy_m
    assert np.array_equal(centre, track.centreline_xy_m)
    right = make_driver("pure_pursuit", terrain, lane_offset_m=1.5).route_xy_m
    assert right.shape == centre.shape
    assert np.allclose(np.linalg.norm(right - centre, axis=1), 1.5)


def test_an_unknown_name_names_the_field() -> None:
    with pytest.raises(ConfigError, match=r"driver.*unknown driver 'sunday'"):
        make_driver("sunday", braking_track(ditch_distance_m=20.0, seed=0, rough=False))


def test_settings_change_the_drivers_config_after_its_target_speed(terrain) -> None:
    observation = ObservationConfig()
    grid = make_driver(
        "grid_planner",
        terrain,
        target_speed_mps=3.0,
        observation=observation,
        settings={"planner": {"bend_steps": 1, "pursuit": {"lookahead_m": 3}}, "memory_steps": 0},
    )
    assert grid.config.planner.bend_steps == 1 and grid.config.memory_steps == 0
    assert (
        grid.config.planner.pursuit.lookahead_m == 3.0 and grid.config.planner.pursuit.target_speed_mps == 3.0
    )
    pursuit = make_driver("pure_pursuit", terrain, target_speed_mps=3.0, settings={"target_speed_mps": 2.0})
    assert pursuit.config.target_speed_mps == 2.0
    assert make_driver("reckless", terrain, settings={}).config == make_driver("reckless", terrain).config


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"planner": {"bend_stepz": 1}}, r"driver_settings: planner\.bend_stepz: no such setting"),
        ({"planner": {"bend_steps": -1}}, r"driver_settings: .*bend_steps.*must be an int >= 0"),
        ({"planner": 1}, r"driver_settings: planner: is a group of settings"),
        (["planner.bend_steps=1"], r"driver_settings: must be a table"),
    ],
)
def test_a_bad_setting_names_the_field_and_its_path(terrain, settings, message) -> None:
    with pytest.raises(ConfigError, match=message):
        make_driver("grid_planner", terrain, observation=ObservationConfig(), settings=settings)
