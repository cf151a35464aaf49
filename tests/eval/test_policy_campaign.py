"""Policy evaluation: episode metrics from a real episode, the summary from hand-made rows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from negobs_gym.drivers.model import ModelDriver
from negobs_gym.envs import make_env
from negobs_gym.errors import ConfigError
from negobs_gym.eval.campaign import format_row
from negobs_gym.eval.episode import EpisodeStop, drive_episode
from negobs_gym.eval.policy_campaign import COLUMNS, PolicyCampaignConfig, episodes, summarize
from tests.helpers import write_vetoes_csv

ORACLE = ["observation.source=oracle"]


class FixedAction:
    """A driver that always sends one action (throttle, steering)."""

    def __init__(self, throttle: float, steering: float) -> None:
        self.action = np.array([throttle, steering], np.float32)

    def reset(self, seed: int) -> None:
        pass

    def act(self, obs, info) -> np.ndarray:
        return self.action


@pytest.mark.parametrize(("steering", "leaves_the_track"), [(0.0, False), (1.0, True)])
def test_off_track_steps_count_the_steps_beside_the_track(steering: float, leaves_the_track: bool) -> None:
    env = make_env("negobs_gym/Braking-v1", ORACLE)
    r = drive_episode(env, FixedAction(0.3, steering), seed=0, filter=False, stop=EpisodeStop(max_steps=30))
    env.close()
    assert 0 <= r.off_track_steps <= r.steps == 30
    # straight on from the centre line stays on the 6 m track; full lock leaves it within 3 s
    assert r.left_track is leaves_the_track and not r.ended_off_track  # Braking-v1 has no such rule


@pytest.mark.parametrize(("steering", "leaves_the_track"), [(0.0, False), (1.0, True)])
def test_leaving_the_track_ends_an_offroad_nav_v2_episode_and_is_recorded(steering, leaves_the_track) -> None:
    env = make_env("negobs_gym/OffroadTrack-v0", ORACLE)
    r = drive_episode(env, FixedAction(1.0, steering), seed=0, filter=False, stop=EpisodeStop(max_steps=40))
    env.close()
    assert r.ended_off_track is leaves_the_track and r.metrics()["left_track"] is leaves_the_track
    # the rule ends the episode at the first step beside the track, before the step limit
    assert (r.steps < 40 and r.off_track_steps == 1) if leaves_the_track else r.off_track_steps == 0


def test_summary_shares_off_track_steps_over_all_steps(tmp_path: Path) -> None:
    def row(flt: str, seed: int, goal: int, steps: int, off: int) -> str:
        values = {c: 0 for c in COLUMNS}
        left = int(off > 0 and not goal)
        values.update(episode=f"{flt}.{seed}", env="e", filter=flt, seed=seed, success=1 - left, goal=goal)
        values.update(left_track=left, veto_events=seed + 1)
        values.update(progress_m=10.0, distance_m=20.0, steps=steps, off_track_steps=off)
        values.update(stopped=int(not goal and not left), steered_steps=seed + 2)
        return format_row([values[c] for c in COLUMNS])

    rows = [row("filter", 0, 1, 100, 30), row("filter", 1, 0, 50, 0), row("nofilter", 0, 0, 10, 10)]
    path = tmp_path / "policy.csv"
    path.write_text(",".join(COLUMNS) + "\n" + "\n".join(rows) + "\n")
    s = summarize(path)
    assert s["filter"]["off_track_share"] == pytest.approx(30 / 150)
    assert s["filter"]["goals"] == 1 and s["filter"]["steps"] == 150
    assert s["filter"]["left_track"] == 0 and s["filter"]["successes"] == 2
    assert s["filter"]["veto_events"] == 3 and s["filter"]["veto_events_per_km"] == pytest.approx(3 / 0.04)
    assert s["filter"]["stopped"] == 1 and s["filter"]["steered_steps"] == 2 + 3
    assert s["nofilter"]["off_track_share"] == 1.0 and s["nofilter"]["stopped"] == 0
    assert s["nofilter"]["left_track"] == 1 and s["nofilter"]["success_rate"] == 0.0
    assert s["filter"]["median_veto_error_m"] is None  # no vetoes.csv given
    vetoes = tmp_path / "vetoes.csv"  # the median of every judged veto's error, per filter setting
    nan = float("nan")
    judged = [("veto", 0.3, 1), ("veto", -0.1, 0), ("veto", 2.0, 1), ("missed", nan, 0), ("veto", nan, 1)]
    write_vetoes_csv(vetoes, [("filter.0", "filter", *judgement) for judgement in judged])
    s = summarize(path, vetoes)
    assert s["filter"]["median_veto_error_m"] == pytest.approx(0.3)
    assert s["filter"]["median_onset_veto_error_m"] == pytest.approx(1.15)  # 0.3 and 2.0 began events
    assert s["nofilter"]["median_veto_error_m"] is None and s["nofilter"]["median_onset_veto_error_m"] is None
    old = tmp_path / "old.csv"  # written before the left_track column
    kept = [c for c in COLUMNS if c != "left_track"]
    old.write_text(",".join(kept) + "\n" + ",".join("0" for _ in kept) + "\n")
    with pytest.raises(ConfigError, match=r"lacks the columns \['left_track'\]"):
        summarize(old)


def test_a_shipped_policy_is_named_in_the_config_and_loaded_by_name() -> None:
    config = PolicyCampaignConfig(model_path="ppo_offroad_nav_v1")
    assert config.model_path == "ppo_offroad_nav_v1"  # not this install's path to it
    driver = ModelDriver("ppo_offroad_nav_v1")
    assert driver.model.observation_space is not None
    with pytest.raises(ConfigError, match="model_path"):
        PolicyCampaignConfig(model_path="no_such_policy")
    with pytest.raises(ConfigError, match="model_path"):
        ModelDriver("no_such_policy")


def test_overrides_change_the_episodes_scenario_and_bad_ones_are_named() -> None:
    config = PolicyCampaignConfig(model_path="ppo_offroad_nav_v1", seeds=1, overrides=tuple(ORACLE))
    assert len(episodes(config)) == 2 and all(e.args["overrides"] == ORACLE for e in episodes(config))
    assert all(
        "overrides" not in e.args for e in episodes(PolicyCampaignConfig(model_path="ppo_offroad_nav_v1"))
    )
    with pytest.raises(ConfigError, match=r"observation\.source"):
        PolicyCampaignConfig(model_path="ppo_offroad_nav_v1", overrides=("observation.source=radar",))
    with pytest.raises(ConfigError, match="overrides"):
        PolicyCampaignConfig(model_path="ppo_offroad_nav_v1", overrides="observation.source=oracle")
    with pytest.warns(DeprecationWarning, match="overrides="):  # the old field, one release more
        old = PolicyCampaignConfig(model_path="ppo_offroad_nav_v1", source="oracle")
    assert old.overrides == ('observation.source="oracle"',)


def test_the_old_episode_function_warns_and_gives_the_loops_metrics() -> None:
    from negobs_gym.eval.braking_campaign import run_driven_episode

    with pytest.warns(DeprecationWarning, match="drive_episode"):
        m = run_driven_episode(make_env("negobs_gym/Braking-v1", ORACLE), FixedAction(1.0, 0.0), 0, False, 5)
    env = make_env("negobs_gym/Braking-v1", ORACLE)
    r = drive_episode(env, FixedAction(1.0, 0.0), seed=0, filter=False, stop=EpisodeStop(max_steps=5))
    env.close()
    assert {k: m[k] for k in r.metrics()} == r.metrics() and m["steps"] == 5
    assert [p[:4] for p in m["path"]] == list(r.path) and m["judgements"] == []


@pytest.mark.parametrize(("filtered", "entered"), [(False, True), (True, False)])
def test_a_scripted_driver_named_as_the_model_runs_the_same_campaign(filtered: bool, entered: bool) -> None:
    from negobs_gym.eval.campaign import Episode
    from negobs_gym.eval.policy_campaign import run_episode

    config = PolicyCampaignConfig(
        model_path="reckless", env_id="negobs_gym/Braking-v1", overrides=tuple(ORACLE)
    )
    args = {**episodes(config)[0].args, "filtered": filtered, "seed": 3}
    row = dict(zip(COLUMNS, run_episode(Episode("x", args))["policy"][0].split(","), strict=True))
    assert row["entered"] == str(int(entered))  # the reckless driver: into the ditch unless vetoed
    assert (int(row["vetoes"]) > 0) == filtered


def test_a_scripted_driver_is_not_looked_up_as_a_saved_model() -> None:
    assert PolicyCampaignConfig(model_path="track_planner").model_path == "track_planner"
    with pytest.raises(ConfigError, match="model_path"):
        PolicyCampaignConfig(model_path="track_planer")
