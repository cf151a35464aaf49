"""Vehicle poses of a recorded drive, so that multi-frame fusion sees the vehicle move.

Paper N fuses pairs over frames in the world frame of the INS pose (Eq. 15/16); a recording alone
has no pose, and taken as standing still a moving vehicle's pairs land in the wrong place. A
poses file gives one pose per frame of the sequence, in order, as a CSV with a header naming at
least ``x, y, z, roll, pitch, yaw`` (other columns, e.g. ``timestamp``, are ignored): metres and
radians in ROS REP-103 axes, the frame the recordings are read in (body x forward, y left, z up;
yaw counter-clockwise from the world x axis, positive pitch nose down, positive roll right side
down), as an odometry or INS export gives them. :func:`pose_from_ros` converts each to this
package's :class:`~negobs_gym.core.pose.Pose` (vehicle Y forward, X right; yaw 0 facing world +Y).

Timed poses, a :class:`PoseTrack` interpolated at each frame's time, come from a CSV with a
``timestamp`` column (:func:`read_pose_track_csv`) or a bag's odometry topic
(:func:`negobs_gym.detector.io.bags.bag_pose_track`).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.errors import ScanError

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

__all__ = [
    "POSE_COLUMNS",
    "TIME_COLUMN",
    "PoseTrack",
    "pose_from_ros",
    "pose_from_ros_transform",
    "read_pose_track_csv",
    "read_poses_csv",
]

POSE_COLUMNS = ("x", "y", "z", "roll", "pitch", "yaw")
#: The column of a timed poses CSV (:func:`read_pose_track_csv`) that says when each pose holds [s].
TIME_COLUMN = "timestamp"


def pose_from_ros(x: float, y: float, z: float, roll: float, pitch: float, yaw: float) -> Pose:
    """The :class:`Pose` of a body whose ROS pose (REP-103, world = the same axes) is given.

    Same world frame and position; the body's forward axis is ROS x but this package's Y, so the
    yaw turns by -90 deg, and ROS pitches about the left axis (nose down) where this package
    pitches about the right one (nose up).
    """
    return Pose(x=x, y=y, z=z, roll=roll, pitch=-pitch, yaw=yaw - math.pi / 2)


def read_poses_csv(path: str | os.PathLike[str]) -> list[Pose]:
    """Poses of a CSV file (module note), one per data row, in order.

    Raises:
        ScanError: an unreadable or empty file, a missing column, or a value that is not a finite
            number (named by row and column).
    """
    return [pose_from_ros(*values) for values in _csv_rows(path, POSE_COLUMNS)]


def read_pose_track_csv(path: str | os.PathLike[str], *, max_gap_s: float = 0.1) -> PoseTrack:
    """Timed poses of a CSV file: a ``timestamp`` column [s] besides the pose columns (module note),
    rows in any order, as a :class:`PoseTrack` read at each frame's time (an INS log beside a
    Velodyne capture, on the clock the frames are timed by).

    Raises:
        ScanError: as :func:`read_poses_csv` (the ``timestamp`` column included), or two rows at
            one time.
    """
    from scipy.spatial.transform import Rotation

    rows = np.asarray(_csv_rows(path, (TIME_COLUMN, *POSE_COLUMNS)), dtype=np.float64)
    order = np.argsort(rows[:, 0], kind="stable")
    rows = rows[order]
    quaternions = Rotation.from_euler("xyz", rows[:, 4:7]).as_quat()  # ROS roll, pitch, yaw
    try:
        return PoseTrack(rows[:, 0], rows[:, 1:4], quaternions, max_gap_s=max_gap_s)
    except ScanError as error:
        raise ScanError(f"{os.fspath(path)}: {error}") from error


def _csv_rows(path: str | os.PathLike[str], columns: tuple[str, ...]) -> list[tuple[float, ...]]:
    """The ``columns`` of every data row of a CSV file, as finite numbers."""
    name = os.fspath(path)
    try:
        with open(name, newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle, skipinitialspace=True)
            rows = list(reader)
            header = [h.strip() for h in reader.fieldnames or ()]
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ScanError(f"{name}: cannot read poses ({type(error).__name__}: {error})") from error
    if not rows:
        raise ScanError(f"{name}: no poses (a header and one row per frame: {', '.join(columns)})")
    missing = [c for c in columns if c not in header]
    if missing:
        raise ScanError(f"{name}: missing pose columns {missing}; the header has {header}")
    out = []
    for n, row in enumerate(rows, start=2):  # line 1 is the header
        row = {(k or "").strip(): v for k, v in row.items()}
        values = []
        for column in columns:
            text = row.get(column)
            try:
                value = float(text)
            except (TypeError, ValueError):
                value = math.nan
            if not math.isfinite(value):
                raise ScanError(f"{name}: line {n}, column {column}: not a finite number ({text!r})")
            values.append(value)
        out.append(tuple(values))
    return out


@dataclass(frozen=True, eq=False)
class PoseTrack:
    """Timed ROS poses of a drive (an odometry topic), read at any time in their span.

    Attributes:
        times_s: (N,) strictly increasing times [s], on the clock of the frames they are read at.
        position_m: (N, 3) ROS world positions.
        quaternion_xyzw: (N, 4) ROS body-to-world orientations (normalised here).
        max_gap_s: How far before the first or after the last pose a frame may lie and take that
            pose (a cloud stamped just outside the odometry's span); farther is an error.
    """

    times_s: np.ndarray
    position_m: np.ndarray
    quaternion_xyzw: np.ndarray
    max_gap_s: float = 0.1

    def __post_init__(self) -> None:
        t = np.asarray(self.times_s, dtype=np.float64)
        xyz = np.asarray(self.position_m, dtype=np.float64)
        q = np.asarray(self.quaternion_xyzw, dtype=np.float64)
        if t.ndim != 1 or t.size == 0 or xyz.shape != (t.size, 3) or q.shape != (t.size, 4):
            raise ScanError(
                "pose track: need N times, (N, 3) positions, (N, 4) quaternions; "
                f"got {t.shape}, {xyz.shape}, {q.shape}"
            )
        if not (np.isfinite(t).all() and np.isfinite(xyz).all() and np.isfinite(q).all()):
            raise ScanError("pose track: a time, position or quaternion is not finite")
        if (np.diff(t) <= 0).any():
            raise ScanError("pose track: times must increase strictly (one pose per time)")
        norm = np.linalg.norm(q, axis=1)
        if (norm < 1e-9).any():
            raise ScanError("pose track: a quaternion has zero length")
        if not (math.isfinite(self.max_gap_s) and self.max_gap_s >= 0):
            raise ScanError(f"pose track: max_gap_s must be finite and >= 0, got {self.max_gap_s}")
        object.__setattr__(self, "times_s", t)
        object.__setattr__(self, "position_m", xyz)
        object.__setattr__(self, "quaternion_xyzw", q / norm[:, None])

    def at(self, time_s: float) -> Pose:
        """The pose at ``time_s``: positions interpolated linearly, orientations by slerp.

        Raises:
            ScanError: ``time_s`` lies more than ``max_gap_s`` outside the track's span.
        """
        return pose_from_ros_transform(*self.transform_at(time_s))

    def transform_at(self, time_s: float) -> tuple[np.ndarray, Rotation]:
        """The ROS body-to-world transform at ``time_s`` (position, rotation), as :meth:`at` reads it."""
        from scipy.spatial.transform import Rotation, Slerp

        t = self.times_s
        if not (t[0] - self.max_gap_s <= time_s <= t[-1] + self.max_gap_s):
            raise ScanError(
                f"no pose at t = {time_s:.3f} s: the poses span {t[0]:.3f}-{t[-1]:.3f} s "
                f"(+- {self.max_gap_s} s)"
            )
        time_s = min(max(time_s, t[0]), t[-1])
        i = int(np.clip(np.searchsorted(t, time_s, side="right") - 1, 0, max(t.size - 2, 0)))
        if t.size == 1:
            xyz, rotation = self.position_m[0], Rotation.from_quat(self.quaternion_xyzw[0])
        else:
            w = (time_s - t[i]) / (t[i + 1] - t[i])
            xyz = (1.0 - w) * self.position_m[i] + w * self.position_m[i + 1]
            pair = Rotation.from_quat(self.quaternion_xyzw[i : i + 2])
            rotation = Slerp(t[i : i + 2], pair)([time_s])[0]
        return np.asarray(xyz, dtype=np.float64), rotation


def pose_from_ros_transform(position_m: np.ndarray, rotation: Rotation) -> Pose:
    """The :class:`Pose` of a ROS body-to-world transform (position, scipy rotation)."""
    roll, pitch, yaw = rotation.as_euler("xyz")  # extrinsic x, y, z: ROS roll, pitch, yaw
    return pose_from_ros(*(float(v) for v in position_m), float(roll), float(pitch), float(yaw))
