"""The governor on the shipped blind-crest scene, end to end through the scenario runner."""

from __future__ import annotations

import pytest

from negobs_gym.eval.scenario_runner import run_scenario
from negobs_gym.safety import SafetyFilterConfig


@pytest.mark.slow
@pytest.mark.parametrize(("mode", "stops"), [("brake", False), ("governed", True)])
def test_only_the_governor_stops_before_the_pit_past_the_crest(mode, stops):
    result = run_scenario("pit_past_a_crest_25kmh", filter=SafetyFilterConfig(mode=mode), seed=3)
    assert result.entered_negative_obstacle is not stops
    assert result.stopped_before is stops


@pytest.mark.slow
def test_the_crest_scene_names_the_governed_mode_itself():
    result = run_scenario("pit_past_a_crest_25kmh", seed=4)  # the scene's own [run]: governed
    assert result.passed, result.failures
