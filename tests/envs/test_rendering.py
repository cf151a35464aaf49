"""rgb_array frames (moviepy is not installed here, so RecordVideo is tested only when it is)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs


def test_rgb_frames_have_a_fixed_shape_and_follow_the_vehicle() -> None:
    env = gym.make("negobs_gym/Braking-v0", render_mode="rgb_array")
    env.reset(seed=2)
    first = env.render()
    for _ in range(5):
        env.step(np.array([0.5, 0.0], np.float32))
    later = env.render()
    assert first.shape == later.shape and first.dtype == np.uint8
    assert not np.array_equal(first, later)  # the vehicle and its path moved
    env.close()


def test_render_is_none_without_a_render_mode() -> None:
    env = gym.make("negobs_gym/Braking-v0")
    env.reset(seed=0)
    assert env.render() is None
    env.close()


def test_bad_render_mode_is_refused() -> None:
    from negobs_gym.envs.scenarios import BrakingEnv

    with pytest.raises(ValueError, match="render_mode"):
        BrakingEnv(render_mode="ascii")


def test_record_video_writes_a_file(tmp_path) -> None:
    pytest.importorskip("moviepy")
    env = gym.wrappers.RecordVideo(gym.make("negobs_gym/Braking-v0", render_mode="rgb_array"), str(tmp_path))
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.zeros(2, np.float32))
    env.close()
    assert list(tmp_path.glob("*.mp4"))
