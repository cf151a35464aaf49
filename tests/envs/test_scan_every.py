"""``ObservationConfig.scan_every``: a LiDAR frame every k-th control step, carried between."""

import numpy as np
import pytest

from negobs_gym.core.grid import carry_layer, carry_points
from negobs_gym.envs.scenarios import BrakingEnv
from negobs_gym.errors import ConfigError
from negobs_gym.safety import BrakingSafetyFilter
from negobs_gym.spec import ObservationConfig

COAST = np.array([0.0, 0.0], np.float32)


def _env(scan_every: int, render_mode: str | None = None, **observation) -> BrakingEnv:
    """Braking-v0 at 25 km/h from the start (paper N §4), a frame every ``scan_every`` steps."""
    settings = {"scan_every": scan_every, **observation}
    changes = {f"observation.{key}": value for key, value in settings.items()}
    return BrakingEnv(overrides={"episode.time_limit_s": 30.0, **changes}, render_mode=render_mode)


def _ranges(env: BrakingEnv) -> np.ndarray:
    return np.concatenate([s.ranges_m.ravel() for s in env.perception.scans.values()])


def test_frames_equal_an_every_step_runs_and_the_steps_between_carry_the_last_one() -> None:
    """Same seed and actions: every other step's scans are those of a frame-every-step env, bit for
    bit (the noise key of a skipped frame is drawn all the same); between frames nothing is cast,
    the grid is the last frame's moved to the current INS pose and so are the filter's hazards,
    which age one control period."""
    every, pair = _env(1), _env(2, downsample=1)
    every.reset(seed=1)
    obs, _ = pair.reset(seed=1)
    carried = hazards_carried = 0
    for step in range(31):
        if step:
            every.step(COAST)
            obs, *_ = pair.step(COAST)
        perception = pair.perception
        hazards = pair.hazard_state()
        if step % 2 == 0:
            np.testing.assert_array_equal(_ranges(pair), _ranges(every))
            assert perception.frame_pose == perception.pose
            assert hazards.perception_age_s == 0.0
            frame_obs, frame_hazards, frame_pose = obs["grid"], hazards, perception.pose
            frame_scans = perception.scans
            continue
        assert perception.scans is frame_scans and perception.frame_pose == frame_pose
        assert hazards.perception_age_s == pytest.approx(0.1)
        index = perception.config.grid.carry_index(frame_pose, perception.pose)
        np.testing.assert_array_equal(obs["grid"], [carry_layer(layer, index) for layer in frame_obs])
        np.testing.assert_allclose(
            hazards.negative_obstacles_xy_m,
            carry_points(frame_hazards.negative_obstacles_xy_m, frame_pose, perception.pose),
        )
        carried += int(obs["grid"][-1].any() and not np.array_equal(obs["grid"], frame_obs))
        hazards_carried += len(hazards.negative_obstacles_xy_m) > 0
    assert carried == 15 and hazards_carried >= 5  # every step between frames: moved, not copied
    assert pair.max_perception_age_s == pytest.approx(0.1) and every.max_perception_age_s == 0.0
    every.close()
    pair.close()


def test_the_rendered_returns_follow_the_car_between_frames() -> None:
    """The frame drawn between two scans puts the last scan's returns where they lie now."""
    env = _env(2, render_mode="rgb_array")
    env.reset(seed=0)
    perception = env.perception
    at_frame = perception.points_vehicle()
    env.step(COAST)  # between frames
    assert perception.frame_pose != perception.pose
    np.testing.assert_allclose(
        perception.points_vehicle(),
        perception.pose.to_vehicle(perception.frame_pose.to_world(at_frame)),
    )
    assert perception.points_vehicle()[:, 1].mean() < at_frame[:, 1].mean() - 0.5  # 0.7 m driven
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3
    env.close()


def test_the_filters_timeout_counts_from_the_frames_own_age() -> None:
    """A frame every 3 steps ages the hazards up to 0.2 s, the default timeout: the filter reads
    that age from the env and is never stale between frames."""
    env = _env(3)
    assert env.max_perception_age_s == pytest.approx(0.2)
    guarded = BrakingSafetyFilter(env)
    assert guarded.frame_age_s == pytest.approx(0.2)
    guarded.reset(seed=0)
    ages = []
    for _ in range(9):
        guarded.step(COAST)
        ages.append(guarded.last_decision.perception_age_s)
        assert not guarded.last_decision.perception_stale
    assert max(ages) == pytest.approx(0.2)
    guarded.close()


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2", None])
def test_bad_scan_every_is_refused(bad) -> None:
    with pytest.raises(ConfigError, match="scan_every"):
        ObservationConfig(scan_every=bad)
    with pytest.raises(ConfigError, match="scan_clock"):
        ObservationConfig(scan_clock="wall")


@pytest.mark.parametrize("clock", ["episode", "env"])
def test_scan_clock_puts_the_frames_on_the_episodes_or_the_envs_steps(clock: str) -> None:
    """k = 3 over two episodes of one env, the first ended after 4 steps: ``"episode"`` casts at
    each episode's steps 3, 6, ... (the env's 3, then 7 and 10); ``"env"`` at the env's steps 3,
    6, 9 (multiples of 3 since it was made), as every env of a lockstep vector env would; each
    reset casts a frame."""
    env = _env(3, scan_clock=clock)
    frames, count = [], 0
    for seed, steps in ((0, 4), (1, 7)):
        env.reset(seed=seed)
        assert env.hazard_state().perception_age_s == 0.0
        for _ in range(steps):
            env.step(COAST)
            count += 1
            if env.hazard_state().perception_age_s == 0.0:
                frames.append(count)
    assert frames == ([3, 7, 10] if clock == "episode" else [3, 6, 9])
    env.close()
