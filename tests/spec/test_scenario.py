"""Scenario specs: TOML/dict loading, round trips, field-named errors, seeded range sampling."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from negobs_gym.errors import ConfigError
from negobs_gym.spec import Range, ScenarioSpec, load_scenario, scenario_names, spec_from_toml, spec_to_toml
from negobs_gym.spec.scenario import TERMINATION_RULES

PIT_TOML = """
name = "my_pit"
terminations = ["entered_negative_obstacle", "stopped"]

[terrain.course]
length_m = 40.0

[[obstacles]]
kind = "pit"
length_m = 1.0
width_m = 1.0
depth_m = 0.6
station_m = [12, 20]
"""


def test_toml_spec_loads_with_defaults_and_ranges() -> None:
    spec = spec_from_toml(PIT_TOML)
    assert spec.obstacles[0].station_m == Range(low=12.0, high=20.0)
    assert spec.obstacles[0].depth_m == 0.6
    assert spec.terrain.course.length_m == 40.0
    assert spec.terminations == ("entered_negative_obstacle", "stopped")
    assert spec.episode.max_episode_steps == 300  # 30 s at 10 Hz by default


def test_ranges_are_drawn_from_the_given_generator_only() -> None:
    spec = spec_from_toml(PIT_TOML)
    a = spec.sample(np.random.default_rng(3)).terrain
    b = spec.sample(np.random.default_rng(3)).terrain
    c = spec.sample(np.random.default_rng(4)).terrain
    np.testing.assert_array_equal(a.heightfield.heights_m, b.heightfield.heights_m)
    centre = [t.negative_obstacles[0].centre_xy_m[1] for t in (a, c)]
    assert all(12.0 <= y <= 20.0 for y in centre)
    assert centre[0] != centre[1]  # another seed, another station


@pytest.mark.parametrize(
    ("patch", "field"),
    [
        ({"obstacles": [{"station_m": 10, "depth_m": -0.6}]}, "obstacles[0].depth_m"),
        ({"obstacles": [{"station_m": 10, "kind": "hole"}]}, "obstacles[0].kind"),
        ({"obstacles": [{"station_m": [20, 10]}]}, "obstacles[0].station_m"),
        ({"obstacles": [{"station_m": 10, "depht_m": 0.6}]}, "obstacles[0].depht_m"),
        ({"start": {"speed_mps": -1.0}}, "start.speed_mps"),
        ({"episode": {"time_limit_s": 0.0}}, "episode.time_limit_s"),
        ({"episode": {"control_hz": "fast"}}, "episode.control_hz"),
        ({"task": {"kind": "fly"}}, "task.kind"),
        ({"terminations": ["stoped"]}, "terminations[0]"),
        ({"reward": {"progres": 1.0}}, "reward.progres"),
        ({"observation": {"channels": ["negative", "bogus"]}}, "observation.channels"),
        ({"observation": {"grid": {"cell_m": -0.2}}}, "observation.grid.cell_m"),
        ({"physics": {"time_step_s": 1.0}}, "physics.time_step_s"),
        ({"render": {"height_px": 31}}, "render.height_px"),
        ({"ins": {"position_noise_m": float("nan")}}, "ins.position_noise_m"),
        ({"criteria": {"max_vetoes": -1}}, "criteria.max_vetoes"),
        ({"run": {"policy": "ppo_offroad_nav_v1", "policy_algo": "DQN"}}, "run.policy_algo"),
        ({"terrain": {"course": {"length_m": 40.0, "bogus": 1}}}, "terrain.course.bogus"),
        ({"terrain": {"preset": "braking_track", "params": {"seed": 3}}}, "terrain.params.seed"),
        ({"terrain": {"preset": "no_such_preset"}}, "terrain.preset"),
        ({"terrain": {"preset": "braking_track", "params": {"rough": "yes"}}}, "terrain.params.rough"),
        (
            {"terrain": {"preset": "winding_course", "params": {"n_negative": 2.5}}},
            "terrain.params.n_negative",
        ),
        ({"terrain": {"preset": "bend", "params": {"angle_deg": [60, 30]}}}, "terrain.params.angle_deg"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_invalid_specs_name_the_field(patch: dict, field: str) -> None:
    data = {"name": "bad", "terrain": {"course": {"length_m": 40.0}}, **patch}
    with pytest.raises(ConfigError) as err:
        ScenarioSpec.from_dict(data)
    assert err.value.field == field, str(err.value)


def test_preset_with_an_obstacle_list_is_refused() -> None:
    with pytest.raises(ConfigError, match="obstacles"):
        ScenarioSpec.from_dict(
            {"name": "x", "terrain": {"preset": "rough_track"}, "obstacles": [{"station_m": 5.0}]}
        )


def test_an_obstacle_off_the_terrain_is_named_at_reset() -> None:
    spec = ScenarioSpec.from_dict(
        {
            "name": "x",
            "terrain": {"course": {"length_m": 40.0}},
            "obstacles": [{"station_m": 10.0, "lateral_m": 40.0}],
        }
    )
    with pytest.raises(ConfigError) as err:
        spec.sample(np.random.default_rng(0))
    assert err.value.field.startswith("obstacles[0]")


def test_malformed_toml_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="toml"):
        spec_from_toml("name = ")


@pytest.mark.parametrize("name", scenario_names())
def test_every_shipped_scenario_round_trips(name: str) -> None:
    spec = load_scenario(name)
    assert spec.name == name
    assert ScenarioSpec.from_dict(spec.to_dict()) == spec
    assert spec_from_toml(spec_to_toml(spec)) == spec


def test_unknown_scenario_name_lists_the_shipped_ones() -> None:
    with pytest.raises(ConfigError, match="braking_v1"):
        load_scenario("no_such_scene")


# -- property: any valid spec round-trips through dict and TOML ------------------------------
_num = st.floats(min_value=0.1, max_value=50.0, allow_nan=False, allow_infinity=False)


def _number(lo: float, hi: float):
    value = st.floats(min_value=lo, max_value=hi, allow_nan=False, allow_infinity=False)
    ranged = st.tuples(value, value).map(lambda t: [min(t), max(t)])
    return st.one_of(value, ranged)


_obstacle = st.fixed_dictionaries(
    {"station_m": _number(1.0, 35.0)},
    optional={
        "kind": st.sampled_from(["pit", "ditch", "trench", "crater"]),
        "length_m": _number(0.3, 3.0),
        "width_m": _number(0.3, 3.0),
        "depth_m": _number(0.3, 1.5),
        "wall_slope_deg": _number(30.0, 90.0),
        "lateral_m": _number(-3.0, 3.0),
        "yaw_deg": _number(-45.0, 45.0),
    },
)
_positive = st.fixed_dictionaries(
    {"station_m": _number(1.0, 35.0)},
    optional={
        "kind": st.sampled_from(["rock", "box", "mound", "vehicle", "pedestrian"]),
        "size_m": st.tuples(_num, _num, _num).map(list),
        "lateral_m": _number(-3.0, 3.0),
    },
)
_spec = st.fixed_dictionaries(
    {
        "name": st.text(min_size=1, max_size=20).filter(str.strip),
        "terrain": st.just({"course": {"length_m": 40.0}}),
    },
    optional={
        "description": st.text(max_size=40),
        "obstacles": st.lists(_obstacle, max_size=3),
        "positive_obstacles": st.lists(_positive, max_size=2),
        "start": st.fixed_dictionaries(
            {}, optional={"speed_mps": _number(0.0, 10.0), "lateral_m": _number(-1, 1)}
        ),
        "episode": st.fixed_dictionaries(
            {}, optional={"time_limit_s": _num, "control_hz": st.sampled_from([5.0, 10.0])}
        ),
        "task": st.fixed_dictionaries(
            {}, optional={"kind": st.sampled_from(["reach_goal", "stop_before_hazard"])}
        ),
        "reward": st.fixed_dictionaries(
            {}, optional={"stopped": st.floats(-100, 100), "time": st.floats(-1, 0)}
        ),
        "terminations": st.lists(st.sampled_from(TERMINATION_RULES), unique=True),
        "criteria": st.fixed_dictionaries(
            {}, optional={"entered_negative_obstacle": st.booleans(), "max_vetoes": st.integers(0, 100)}
        ),
    },
)


@settings(max_examples=60, deadline=None)
@given(_spec)
def test_spec_round_trips_through_dict_and_toml(data: dict) -> None:
    spec = ScenarioSpec.from_dict(data)
    again = ScenarioSpec.from_dict(spec.to_dict())
    assert again == spec
    assert spec_from_toml(spec_to_toml(spec)) == spec
    assert dataclasses.replace(spec, name="other") != spec
