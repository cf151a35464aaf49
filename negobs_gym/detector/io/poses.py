"""Vehicle poses of a recorded drive, so that multi-frame fusion sees the vehicle move.

Paper N fuses pairs over frames in the world frame of the INS pose (Eq. 15/16); a recording alone
has no pose, and taken as standing still a moving vehicle's pairs land in the wrong place. A
poses file gives one pose per frame of the sequence, in order, as a CSV with a header naming at
least ``x, y, z, roll, pitch, yaw`` (other columns, e.g. ``timestamp``, are ignored): metres and
radians in ROS REP-103 axes, the frame the recordings are read in (body x forward, y left, z up;
yaw counter-clockwise from the world x axis, positive pitch nose down, positive roll right side
down), as an odometry or INS export gives them. :func:`pose_from_ros` converts each to this
package's :class:`~negobs_gym.core.pose.Pose` (vehicle Y forward, X right; yaw 0 facing world +Y).
"""

from __future__ import annotations

import csv
import math
import os

from negobs_gym.core.pose import Pose
from negobs_gym.errors import ScanError

__all__ = ["POSE_COLUMNS", "pose_from_ros", "read_poses_csv"]

POSE_COLUMNS = ("x", "y", "z", "roll", "pitch", "yaw")


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
    name = os.fspath(path)
    try:
        with open(name, newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle, skipinitialspace=True)
            rows = list(reader)
            header = [h.strip() for h in reader.fieldnames or ()]
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ScanError(f"{name}: cannot read poses ({type(error).__name__}: {error})") from error
    if not rows:
        raise ScanError(f"{name}: no poses (a header and one row per frame: {', '.join(POSE_COLUMNS)})")
    missing = [c for c in POSE_COLUMNS if c not in header]
    if missing:
        raise ScanError(f"{name}: missing pose columns {missing}; the header has {header}")
    poses = []
    for n, row in enumerate(rows, start=2):  # line 1 is the header
        row = {(k or "").strip(): v for k, v in row.items()}
        values = []
        for column in POSE_COLUMNS:
            text = row.get(column)
            try:
                value = float(text)
            except (TypeError, ValueError):
                value = math.nan
            if not math.isfinite(value):
                raise ScanError(f"{name}: line {n}, column {column}: not a finite number ({text!r})")
            values.append(value)
        poses.append(pose_from_ros(*values))
    return poses
