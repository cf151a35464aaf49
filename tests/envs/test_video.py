"""EpisodeVideo: frames streamed to an MP4 that appears whole at the end, or not at all."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from negobs_gym.envs.video import EpisodeVideo, optional_video, recording
from negobs_gym.errors import ConfigError, UsageError

imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")


def _frames(n: int, shape: tuple[int, int] = (48, 64)) -> list[np.ndarray]:
    """Frames of one flat colour each, the colour moving with the index (easy to decode back)."""
    frames = []
    for k in range(n):
        frame = np.zeros((*shape, 3), np.uint8)
        frame[:] = (20 * k % 256, 255 - 20 * k % 256, 128)
        frames.append(frame)
    return frames


def _decode(path) -> tuple[tuple[int, int], list[np.ndarray]]:
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = reader.__next__()
    w, h = meta["size"]
    frames = [np.frombuffer(b, np.uint8).reshape(h, w, 3) for b in reader]
    return (h, w), frames


def test_every_frame_is_in_the_file_at_its_size_and_colour(tmp_path) -> None:
    path = tmp_path / "sub" / "episode.mp4"
    frames = _frames(12)
    with EpisodeVideo(path, fps=10) as video:
        for frame in frames:
            video.add(frame)
        assert not path.exists()  # appears only when closed
    assert video.frames == 12
    size, decoded = _decode(path)
    assert size == (48, 64) and len(decoded) == 12
    for got, sent in zip(decoded, frames, strict=True):  # H.264 is lossy: the colour, within a few levels
        assert np.abs(got.astype(int).mean(axis=(0, 1)) - sent[0, 0]).max() < 6
    assert [p.name for p in path.parent.iterdir()] == ["episode.mp4"]  # no temp file left


def test_an_episode_that_raises_leaves_no_file(tmp_path) -> None:
    path = tmp_path / "episode.mp4"
    with pytest.raises(KeyError), EpisodeVideo(path) as video:
        video.add(_frames(1)[0])
        raise KeyError("the episode failed")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        (np.zeros((48, 64, 3), np.float32), "uint8"),
        (np.zeros((48, 64), np.uint8), r"\(H, W, 3\)"),
        (np.zeros((47, 64, 3), np.uint8), "even"),
    ],
)
def test_bad_frames_are_named_and_leave_no_file(tmp_path, frame, message) -> None:
    with (
        pytest.raises(ConfigError, match=r"^frame: .*" + message) as error,
        EpisodeVideo(tmp_path / "v.mp4") as video,
    ):
        video.add(frame)
    assert error.value.field == "frame" and isinstance(error.value, ValueError)
    assert list(tmp_path.iterdir()) == []


def test_a_frame_of_another_size_and_an_empty_video_are_refused(tmp_path) -> None:
    with (
        pytest.raises(ConfigError, match=r"^frame: shape .* differs"),
        EpisodeVideo(tmp_path / "a.mp4") as video,
    ):
        video.add(_frames(1)[0])
        video.add(_frames(1, (48, 66))[0])
    with pytest.raises(ConfigError, match=r"^frames: no frames were added"), EpisodeVideo(tmp_path / "b.mp4"):
        pass
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(UsageError, match="with block"):  # a RuntimeError too
        EpisodeVideo(tmp_path / "c.mp4").add(_frames(1)[0])
    for fps in (0.0, -1.0, float("nan")):
        with pytest.raises(ConfigError, match="fps"):
            EpisodeVideo(tmp_path / "d.mp4", fps=fps)


def test_optional_video_records_only_when_given_a_path(tmp_path) -> None:
    with optional_video(None) as video:
        assert video is None
    with optional_video(tmp_path / "v.mp4", fps=5) as video:
        video.add(_frames(1)[0])
    assert video.fps == 5 and (tmp_path / "v.mp4").is_file()


class _CountingEnv(gym.Env):
    """Renders a frame whose colour is the number of steps taken."""

    observation_space = gym.spaces.Discrete(1)
    action_space = gym.spaces.Discrete(1)

    def reset(self, *, seed=None, options=None):
        self.k = 0
        return 0, {}

    def step(self, action):
        self.k += 1
        return 0, 0.0, False, False, {}

    def render(self):
        return _frames(self.k + 1)[self.k]


def test_a_recording_env_adds_a_frame_after_the_reset_and_every_step(tmp_path) -> None:
    env = _CountingEnv()
    assert recording(env, None) is env
    with optional_video(tmp_path / "v.mp4") as video:
        wrapped = recording(env, video)
        wrapped.reset(seed=0)
        for _ in range(4):
            wrapped.step(0)
    assert video.frames == 5
    _, decoded = _decode(tmp_path / "v.mp4")
    sent = [_frames(k + 1)[k] for k in range(5)]
    for got, want in zip(decoded, sent, strict=True):
        assert np.abs(got.astype(int).mean(axis=(0, 1)) - want[0, 0]).max() < 6
