"""A researcher's own scenario test, in a few lines: ``python -m pytest examples/test_my_scenario.py``.

The scene is data (TOML): a 0.8 m deep ditch 15-25 m ahead at 25 km/h. The test drives it with the
reckless driver behind the Eq. 18 safety filter on three seeds and asserts on the outcome. A trained
policy is tested the same way: the shipped OffroadNav-v1 policy on the first 15 s of that env's
scenario, behind the filter (a model of your own: ``ModelDriver("outputs/ppo_v1/model.zip")``).
"""

import math

import pytest

from negobs_gym.drivers.model import ModelDriver
from negobs_gym.eval.scenario_runner import run_scenario
from negobs_gym.spec import apply_overrides, load_scenario, spec_from_toml

SCENE = spec_from_toml("""
name = "my_ditch"
terminations = ["entered_negative_obstacle", "stopped"]
[terrain.course]
length_m = 50.0
[[obstacles]]
kind = "ditch"
length_m = 1.0
width_m = 3.0
depth_m = 0.8
station_m = [15, 25]
[start]
speed_mps = 6.944444444444445
[episode]
time_limit_s = 10.0
""")


@pytest.mark.parametrize("seed", range(3))
def test_filter_stops_before_my_ditch(seed):
    result = run_scenario(SCENE, "reckless", filter=True, seed=seed)
    assert result.stopped_before and not result.entered_negative_obstacle, result.line()
    assert result.stop_margin_m > 0.5 and result.false_vetoes == 0
    # judged on the ground truth: no step let through with the ditch well inside R(v), and no veto
    # that put the ditch more than half a metre beyond where it is
    assert result.missed_vetoes == 0 and result.max_veto_error_m < 0.5


@pytest.mark.parametrize("seed", [1000000])
def test_my_policy_behind_the_filter_enters_no_pit(seed):
    spec = apply_overrides(load_scenario("offroad_nav_v1"), ["episode.time_limit_s=15"])
    result = run_scenario(spec, ModelDriver("ppo_offroad_nav_v1"), filter=True, seed=seed)
    assert not result.entered_negative_obstacle and not result.collision, result.line()
    assert math.dist(result.path_xy_m[0], result.path_xy_m[-1]) > 30.0 and result.missed_vetoes == 0
