"""Episode videos: ``rgb_array`` frames streamed to an MP4 file as they are drawn.

gymnasium's ``RecordVideo`` keeps every frame of an episode until it ends (a 60 s episode of
480 x 374 px frames at 10 Hz is ~320 MB); :class:`EpisodeVideo` hands each frame to ffmpeg as it
comes (imageio-ffmpeg, which ships the ffmpeg binary: the ``video`` extra), so memory stays at one
frame. The file appears whole when the video is closed (:func:`negobs_gym.core.files.
atomic_target`), and not at all when the episode raised.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from negobs_gym.core.files import atomic_target
from negobs_gym.errors import ConfigError, MissingDependencyError, UsageError, require

__all__ = ["EpisodeVideo", "FrameRecorder", "optional_video", "recording"]


class EpisodeVideo:
    """An MP4 (H.264, yuv420p) of equally sized (H, W, 3) uint8 frames, written to ``path``.

    Use as a context manager: ``with EpisodeVideo(path, fps=10) as video: video.add(frame)``. H and
    W must be even (yuv420p; the envs' frames are). ``fps``: frames per second of playback, the
    env's control rate for real time.

    Raises:
        ConfigError: ``fps`` not finite and > 0.
        MissingDependencyError: imageio-ffmpeg is not installed (``pip install "negobs_gym[video]"``).
    """

    def __init__(self, path: str | Path, fps: float = 10.0) -> None:
        require(math.isfinite(fps) and fps > 0, "fps", f"must be finite and > 0, got {fps!r}")
        try:
            import imageio_ffmpeg
        except ImportError as exc:
            raise MissingDependencyError(
                "imageio-ffmpeg", "episode videos (extra negobs_gym[video])"
            ) from exc
        self._ffmpeg = imageio_ffmpeg
        self.path = Path(path)
        self.fps = float(fps)
        self.frames = 0
        self._shape: tuple[int, ...] | None = None
        self._writer: Any = None
        self._target: contextlib.AbstractContextManager[Path] | None = None
        self._tmp = self.path  # the temp file ffmpeg writes, from __enter__ on

    def __enter__(self) -> EpisodeVideo:
        self._target = atomic_target(self.path)
        self._tmp = self._target.__enter__()
        return self

    def add(self, frame: np.ndarray) -> None:
        """Append one frame (the first one fixes the video's size)."""
        if self._target is None:
            raise UsageError("EpisodeVideo.add: open the video first (use it in a with block)")
        frame = np.asarray(frame)
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise ConfigError("frame", f"must be (H, W, 3) uint8, got {frame.shape} {frame.dtype}")
        if self._shape is None:
            if frame.shape[0] % 2 or frame.shape[1] % 2:
                raise ConfigError("frame", f"height and width must be even (yuv420p), got {frame.shape[:2]}")
            self._shape = frame.shape
            self._writer = self._ffmpeg.write_frames(
                str(self._tmp),
                (frame.shape[1], frame.shape[0]),
                fps=self.fps,
                codec="libx264",
                macro_block_size=2,  # keep the frame's own (even) size: no rescaling to 16 px blocks
            )
            self._writer.send(None)  # start ffmpeg
        elif frame.shape != self._shape:
            raise ConfigError("frame", f"shape {frame.shape} differs from the video's {self._shape}")
        self._writer.send(np.ascontiguousarray(frame))
        self.frames += 1

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        target, self._target = self._target, None
        if target is None:
            return
        try:
            if self._writer is not None:
                self._writer.close()  # ffmpeg finishes the file
            elif exc_type is None:
                raise ConfigError("frames", f"no frames were added to {self.path}")
        except BaseException as error:
            target.__exit__(type(error), error, error.__traceback__)
            raise
        target.__exit__(exc_type, exc, tb)


@contextlib.contextmanager
def optional_video(path: str | Path | None, fps: float = 10.0) -> Iterator[EpisodeVideo | None]:
    """An :class:`EpisodeVideo` of ``path`` for the ``with`` block, or None when ``path`` is None
    (callers that record on request: ``if video is not None: video.add(env.render())``)."""
    if path is None:
        yield None
        return
    with EpisodeVideo(path, fps=fps) as video:
        yield video


class FrameRecorder(gym.Wrapper):
    """Adds ``env.render()`` to ``video`` after every reset and step, so a driving loop records
    without knowing it (wrap outermost: a safety filter inside has set its decision by then)."""

    def __init__(self, env: gym.Env, video: EpisodeVideo) -> None:
        super().__init__(env)
        self.video = video

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        out = self.env.reset(**kwargs)
        self.video.add(self.env.render())
        return out

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        out = self.env.step(action)
        self.video.add(self.env.render())
        return out


def recording(env: gym.Env, video: EpisodeVideo | None) -> gym.Env:
    """``env`` recording into ``video`` (:class:`FrameRecorder`), or ``env`` itself when None."""
    return env if video is None else FrameRecorder(env, video)
