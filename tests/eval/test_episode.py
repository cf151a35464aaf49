"""The one episode loop: its ends, its driver built on the reset course, its refusals."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from negobs_gym.drivers import ConstantSpeedConfig, ConstantSpeedDriver, RecklessDriver
from negobs_gym.envs import make_env
from negobs_gym.errors import ConfigError
from negobs_gym.eval.episode import EpisodeStop, drive_episode, filter_settings
from negobs_gym.safety.filter import SafetyFilterConfig
from negobs_gym.spec import load_scenario
from negobs_gym.spec.scenario import SCENE_FILTER

ORACLE = ["observation.source=oracle"]


class Brake:
    """Full brake from the start: the car stands within a few steps."""

    def reset(self, seed: int | None = None) -> None:
        pass

    def act(self, obs, info) -> np.ndarray:
        return np.array([-1.0, 0.0], np.float32)


@pytest.mark.parametrize(
    ("fields", "field"),
    [
        ({"max_steps": 0}, "max_steps"),
        ({"max_steps": 2.5}, "max_steps"),
        ({"standstill_s": -1.0}, "standstill_s"),
        ({"standstill_mps": math.nan}, "standstill_mps"),
    ],
)
def test_bad_stop_rules_are_named(fields, field) -> None:
    with pytest.raises(ConfigError, match=field):
        EpisodeStop(**fields)


def test_the_loop_ends_at_max_steps_or_after_standing_still_long_enough() -> None:
    env = make_env("braking_v0", ORACLE)
    capped = drive_episode(env, RecklessDriver(), seed=0, filter=False, stop=EpisodeStop(max_steps=7))
    assert (
        capped.steps == len(capped.path) - 1 == 7
        and not capped.stopped
        and capped.time_s == pytest.approx(0.7)
    )
    assert capped.distance_m > 0 and capped.driver == "RecklessDriver" and not capped.filtered
    # braking_v0 has no stopping rule: the loop's standstill rule ends the episode, 1 s after the
    # speed fell below 0.1 m/s (the 11th step: ten 0.1 s steps sum to just under 1 s)
    held = drive_episode(env, Brake(), seed=0, filter=False, stop=EpisodeStop(standstill_s=1.0))
    env.close()
    speeds = [p.speed_mps for p in held.path]
    first_still = next(k for k, v in enumerate(speeds) if k > 0 and v < 0.1)
    assert held.stopped and held.steps == first_still + 10 and all(v < 0.1 for v in speeds[first_still:])
    assert held.termination == () and not held.truncated  # the loop ended it, not the env
    assert held.max_decel_mps2 > 5.0 and held.final_speed_mps < 0.1
    # standing before the ditch with it still ahead: the stop_before_hazard task is done
    assert held.stopped_before and held.task_done and held.stop_margin_m == pytest.approx(held.final_gap_m)


def test_a_driver_source_is_built_on_the_course_the_reset_drew() -> None:
    seen = []

    def build(env):
        seen.append(env.terrain)
        return ConstantSpeedDriver(ConstantSpeedConfig(target_speed_mps=3.0))

    env = make_env("braking_v0", ORACLE)
    result = drive_episode(
        env, build, seed=3, filter=False, stop=EpisodeStop(max_steps=3), driver_name="slow"
    )
    assert seen == [env.unwrapped.terrain] and result.driver == "slow" and result.steps == 3
    env.close()


def test_the_filter_follows_the_spec_unless_given() -> None:
    rock = load_scenario("rock_on_track_25kmh")
    assert rock.run.filter and rock.filter.stop_for_positive
    assert filter_settings(None, rock) == dataclasses.replace(SCENE_FILTER, stop_for_positive=True)
    assert filter_settings(True, load_scenario("braking_v0")) == SCENE_FILTER
    # Eq. 18 plus hazard memory, holding what lies within 8 m
    assert SCENE_FILTER == SafetyFilterConfig(hazard_memory=True, hazard_memory_hold_m=8.0)
    assert filter_settings(False, rock) is None
    own = SafetyFilterConfig(margin_m=0.5)
    assert filter_settings(own, rock) is own
    crest = load_scenario("pit_past_a_crest_25kmh")  # a scene that names the filter's mode
    assert crest.filter.mode == "governed" and filter_settings(True, crest).mode == "governed"
    capped = dataclasses.replace(crest, filter=dataclasses.replace(crest.filter, mode="cap_speed"))
    assert filter_settings(True, capped).mode == "cap_speed"
    no_run = dataclasses.replace(crest, run=dataclasses.replace(crest.run, filter=False))
    assert filter_settings(None, no_run) is None


def test_a_video_needs_rgb_frames() -> None:
    env = make_env("braking_v0", ORACLE)
    with pytest.raises(ConfigError, match="video_to"):
        drive_episode(env, RecklessDriver(), seed=0, video_to="x.mp4")
    env.close()
