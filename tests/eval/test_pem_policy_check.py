"""The PEM's closed loop on a policy: the same seeds on the detector and PEM grids, the goal gap."""

from __future__ import annotations

from pathlib import Path

import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.eval.pem_check import PolicyCheckConfig, compare_policy


def _summary(goals: int, episodes: int = 20) -> dict:
    return {
        "filter": {
            "episodes": episodes, "goals": goals, "entries": 0, "collisions": 1, "left_track": 2,
            "stopped": 1, "vetoes_per_km": 3.0, "false_vetoes_per_km": 0.5, "mean_progress_m": 90.0,
        }
    }  # fmt: skip


def test_the_goal_gap_is_checked_against_ten_points():
    config = PolicyCheckConfig(policy="ppo_offroad_nav_v1", seeds=20)
    close = compare_policy({"detector": _summary(15), "pem": _summary(17)}, config)
    assert close.passed and close.figures["policy_goal_rate_gap"] == pytest.approx(0.10)
    assert close.figures["policy_goals_detector"] == 15 and close.figures["policy_left_track_pem"] == 2
    far = compare_policy({"detector": _summary(10), "pem": _summary(13)}, config)
    assert not far.checks["check_policy_goal_gap"]
    assert "check_policy_goal_gap=fail" in far.lines()


def test_both_campaigns_run_the_records_env_and_settings_on_each_grid():
    config = PolicyCheckConfig(
        policy="ppo_offroad_nav_v1_pem", seeds=3, overrides=("episode.time_limit_s=30",)
    )
    runs = config.campaigns(None)
    assert runs["detector"].env_id == runs["pem"].env_id == "negobs_gym/OffroadNav-v1"
    assert runs["detector"].seeds == 3 and runs["detector"].filters == (True,)
    assert runs["pem"].overrides[0] == "reward.goal_approach=2.0"  # the record's --set first
    assert runs["detector"].overrides[-2:] == ("episode.time_limit_s=30", "observation.source=detector")
    # no model named: the env draws from the shipped model of its own positive channel
    assert runs["pem"].overrides[-2:] == ("episode.time_limit_s=30", "observation.source=pem")
    named = config.campaigns("some/pem.json")["pem"].overrides
    assert named[-1] == f"observation.pem_model={Path('some/pem.json').resolve()}"
    with pytest.raises(ConfigError, match="policy_seeds"):
        PolicyCheckConfig(policy="ppo_offroad_nav_v1", seeds=0)


def test_a_scripted_driver_runs_on_the_env_given_and_needs_one():
    config = PolicyCheckConfig(policy="track_planner", env_id="offroad_nav_v2", seeds=2)
    runs = config.campaigns(None)
    assert runs["detector"].model_path == runs["pem"].model_path == "track_planner"
    assert runs["pem"].overrides[-1] == "observation.source=pem"
    with pytest.raises(ConfigError, match="--policy-env"):
        PolicyCheckConfig(policy="track_planner").campaigns(None)
