"""Checks of one frame's input shared by the rig detectors: a finite INS pose and named scans."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.errors import ScanError


def check_frame(scans: object, pose: object) -> None:
    """Raise :class:`~negobs_gym.errors.ScanError` naming the problem unless ``pose`` is a finite
    :class:`Pose` and ``scans`` maps sensor names to :class:`StructuredScan` (empty is fine)."""
    if not isinstance(pose, Pose):
        raise ScanError(f"pose must be a Pose, got {type(pose).__name__}")
    if not np.isfinite(pose.as_array()).all():
        raise ScanError(f"pose contains NaN/inf: {pose}")
    if not isinstance(scans, Mapping):
        raise ScanError(f"scans must map sensor names to StructuredScan, got {type(scans).__name__}")
    for name, s in scans.items():
        if not isinstance(s, StructuredScan):
            raise ScanError(f"scans[{name!r}] must be a StructuredScan, got {type(s).__name__}")
