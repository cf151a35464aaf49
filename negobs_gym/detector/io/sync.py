"""Several LiDARs of one recording as one detector update (paper N's rig: a top HDL-64 and two side
HDL-32s, each on its own topic and its own clock).

Each cloud of a *lead* topic makes one update; every other topic contributes its cloud nearest in
time to the lead's, within a window (spinning sensors at 10 Hz that are not phase-locked lie at
most half a revolution apart), each cloud used once. The detector takes one vehicle pose per
update and maps each sensor by its mounting (paper N Eq. 9), so a cloud taken ``dt`` before or
after the lead's is brought to the lead's time by the vehicle's motion over ``dt``
(:func:`scan_at_time`), read from the pose source that gives the update's pose. Given when each
column was fired, the same function deskews a revolution scanned while driving.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io.frame import RecordedFrame
from negobs_gym.errors import ScanError

#: How far [s] another topic's cloud may lie from the lead's and join its update: one revolution
#: at 10 Hz (paper N's Velodynes), so a sensor that dropped a cloud still contributes its neighbour.
SYNC_WINDOW_S = 0.1
#: How long [s] of lead clouds past a lead cloud's window to wait for a topic that has gone quiet
#: (a sensor that stopped, a bag that ends one topic early) before updating without it.
SYNC_LAG_S = 1.0
#: Times across a revolution at which :func:`scan_at_time` reads the poses to deskew (linear between).
DESKEW_SAMPLES = 33


class PoseAtTime(Protocol):
    """A pose source read at any time: :class:`~negobs_gym.detector.io.poses.PoseTrack`,
    :class:`~negobs_gym.detector.io.tf.TransformChain`."""

    def at(self, time_s: float) -> Pose: ...


@dataclass(frozen=True, eq=False)
class SynchronisedFrames:
    """One detector update of several topics.

    Attributes:
        lead: The lead topic's cloud; its time is the update's.
        clouds: Every topic's cloud in this update by topic, the lead's included; a topic with no
            unused cloud within the window is absent.
    """

    lead: RecordedFrame
    clouds: Mapping[str, RecordedFrame]

    @property
    def time_s(self) -> float:
        """The update's time: the lead cloud's."""
        return self.lead.scan.timestamp_s


def synchronise(
    stream: Iterable[tuple[str, RecordedFrame]],
    lead: str,
    others: Sequence[str],
    *,
    window_s: float = SYNC_WINDOW_S,
    lag_s: float = SYNC_LAG_S,
) -> Iterator[SynchronisedFrames]:
    """Group a recording's clouds, ``(topic, frame)`` in the order it holds them, into one update per
    cloud of ``lead``, each with every topic of ``others``' unused cloud nearest in time within
    ``window_s`` (the earlier on a tie). Streaming: a lead cloud waits until each other topic has a
    cloud past its window, or the lead ``lag_s`` more, so memory stays a window's worth of clouds.
    Clouds of other topics are ignored.

    Raises:
        ScanError: ``lead`` among ``others``, a topic named twice, or a window or lag that is
            negative or not finite.
    """
    if lead in others or len(set(others)) != len(others):
        raise ScanError(
            f"synchronise: each topic once, the lead {lead!r} not among the others {list(others)}"
        )
    for name, value in (("window_s", window_s), ("lag_s", lag_s)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ScanError(f"synchronise: {name} must be finite and >= 0, got {value}")
    grouper = _Grouper(lead, others, window_s, lag_s)
    for topic, frame in stream:
        grouper.add(topic, frame)
        yield from grouper.updates(final=False)
    yield from grouper.updates(final=True)


class _Grouper:
    """:func:`synchronise`'s state: lead clouds waiting for their window to fill, and the other
    topics' clouds that a lead may still take."""

    def __init__(self, lead: str, others: Sequence[str], window_s: float, lag_s: float) -> None:
        self.lead, self.window_s, self.lag_s = lead, window_s, lag_s
        self.pending: deque[RecordedFrame] = deque()
        self.waiting: dict[str, list[RecordedFrame]] = {topic: [] for topic in others}
        self.newest = dict.fromkeys([lead, *others], -math.inf)
        self.last_lead = -math.inf  # the time of the last update

    def add(self, topic: str, frame: RecordedFrame) -> None:
        time_s = frame.scan.timestamp_s
        if topic == self.lead:
            self.pending.append(frame)
        elif topic in self.waiting:
            self.waiting[topic].append(frame)
        else:
            return
        self.newest[topic] = max(self.newest[topic], time_s)
        self._forget()

    def updates(self, final: bool) -> Iterator[SynchronisedFrames]:
        while self.pending and (final or self._ready(self.pending[0].scan.timestamp_s)):
            frame = self.pending.popleft()
            self.last_lead = frame.scan.timestamp_s
            chosen = _nearest(self.waiting, self.last_lead, self.window_s)
            yield SynchronisedFrames(frame, {self.lead: frame, **chosen})
            self._forget()

    def _ready(self, time_s: float) -> bool:
        """Every other topic is past the lead's window, or the lead ``lag_s`` beyond it."""
        if self.newest[self.lead] >= time_s + self.window_s + self.lag_s:
            return True
        return all(self.newest[topic] >= time_s + self.window_s for topic in self.waiting)

    def _forget(self) -> None:
        """Drop the clouds no lead can take: before the earliest waiting lead's window (or the last
        update's), or more than the lag behind their own topic's newest."""
        earliest = min((f.scan.timestamp_s for f in self.pending), default=self.last_lead)
        for topic, frames in self.waiting.items():
            cutoff = max(earliest, self.newest[topic] - self.lag_s) - self.window_s
            self.waiting[topic] = [f for f in frames if f.scan.timestamp_s >= cutoff]


def _nearest(
    waiting: dict[str, list[RecordedFrame]], time_s: float, window_s: float
) -> dict[str, RecordedFrame]:
    """Each topic's waiting cloud nearest ``time_s`` within ``window_s``, taken out of ``waiting``."""
    chosen = {}
    for topic, frames in waiting.items():
        gaps = [abs(f.scan.timestamp_s - time_s) for f in frames]
        if gaps and min(gaps) <= window_s:
            chosen[topic] = frames.pop(gaps.index(min(gaps)))
    return chosen


def scan_at_time(
    scan: StructuredScan,
    poses: PoseAtTime,
    time_s: float,
    *,
    column_time_s: np.ndarray | None = None,
) -> StructuredScan:
    """``scan`` as the vehicle frame at ``time_s`` sees it, by ``poses``.

    The vehicle's motion from when a column was fired to ``time_s`` becomes the column's
    :attr:`~negobs_gym.core.scan.StructuredScan.column_motion`; the range image and the mounting
    stay as recorded, so the detector's features read the scan as the sensor saw it (and keep the
    per-ray tables of its mounting) and place what they find where the vehicle at ``time_s`` has
    it. Without ``column_time_s`` the scan is taken as fired at once at its ``timestamp_s``: every
    column gets the same motion (:func:`vehicle_motion`). With it, when each column was fired after
    ``timestamp_s`` (:attr:`RecordedFrame.column_time_s`; NaN = at ``timestamp_s``), each column
    gets its own: the revolution is deskewed (it takes 0.1 s, 0.7 m at 25 km/h).

    Raises:
        ScanError: ``column_time_s`` not one value per column; a time ``poses`` cannot give.
    """
    if column_time_s is None:
        motion = vehicle_motion(poses, scan.timestamp_s, time_s)
        return dataclasses.replace(scan, column_motion=np.broadcast_to(motion, (scan.shape[1], 3, 4)))
    now = poses.at(time_s)
    offsets = np.nan_to_num(np.asarray(column_time_s, dtype=np.float64), nan=0.0)
    if offsets.shape != (scan.shape[1],):
        raise ScanError(
            f"{scan.sensor}: column_time_s has shape {offsets.shape}, the scan {scan.shape[1]} columns"
        )
    # the motion at a few times across the revolution, linear between them (3 ms apart at 10 Hz)
    samples = np.unique(np.linspace(offsets.min(), offsets.max(), DESKEW_SAMPLES))
    motions = np.stack([_as_3x4(*_motion(poses.at(scan.timestamp_s + dt), now)) for dt in samples])
    at = np.interp(offsets, samples, np.arange(samples.size))
    i = np.minimum(at.astype(np.int64), samples.size - 1)
    j = np.minimum(i + 1, samples.size - 1)
    w = (at - i)[:, None, None]
    return dataclasses.replace(scan, column_motion=(1.0 - w) * motions[i] + w * motions[j])


def vehicle_motion(poses: PoseAtTime, from_s: float, to_s: float) -> np.ndarray:
    """``[M | m]`` (3, 4): the vehicle frame at ``from_s`` in the vehicle frame at ``to_s``, by
    ``poses`` (a point ``p`` of the first is ``M p + m`` in the second)."""
    return _as_3x4(*_motion(poses.at(from_s), poses.at(to_s)))


def _as_3x4(turn: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """``[M | m]`` as one (3, 4) array."""
    return np.hstack([turn, shift[:, None]])


def _motion(then: Pose, now: Pose) -> tuple[np.ndarray, np.ndarray]:
    """``(M, m)``: the vehicle frame at ``then`` in the vehicle frame at ``now``."""
    turn = now.rotation.T @ then.rotation
    return turn, now.rotation.T @ (then.translation - now.translation)
