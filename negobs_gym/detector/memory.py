"""A short memory of obstacle points, kept in the world frame of the INS pose.

Neither paper keeps obstacles between frames: each frame's grid holds what that frame saw. A rig
has blind zones near the vehicle, though (the LUX's layers pass over a low rock within ~2 m of the
bumper, the HDL-64's lowest laser meets the ground ~5 m out), so an obstacle drops off a per-frame
grid as the vehicle closes in on it. :class:`PointHold` keeps each frame's points for ``hold_s``
seconds and hands them back in the vehicle frame of a later pose, so a detector can keep marking
them.
"""

from __future__ import annotations

import math

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.errors import require


class PointHold:
    """World-frame points of the frames of the last ``hold_s`` seconds (bounded: older frames, and
    frames stamped after the newest scan, as after a restart without :meth:`reset`, are dropped)."""

    def __init__(self, hold_s: float) -> None:
        require(
            isinstance(hold_s, (int, float)) and math.isfinite(hold_s) and hold_s >= 0,
            "hold_s",
            f"must be finite and >= 0 [s], got {hold_s!r}",
        )
        self.hold_s = float(hold_s)
        self._frames: list[tuple[float, np.ndarray]] = []  # (scan time, (n, 3) world points)

    def reset(self) -> None:
        """Forget every held frame (start of a new run)."""
        self._frames = []

    def recall_and_keep(self, points_vehicle: np.ndarray, pose: Pose, stamp_s: float) -> np.ndarray:
        """(N, 3) vehicle-frame points (at ``pose``) of the frames held from before ``stamp_s``;
        then keeps this frame's ``points_vehicle`` (n, 3), seen at ``pose``, for the next calls."""
        self._frames = [(t, p) for t, p in self._frames if 0.0 <= stamp_s - t <= self.hold_s]
        earlier = self.recall(pose)
        if self.hold_s > 0 and len(points_vehicle):
            self._frames.append((stamp_s, pose.to_world(points_vehicle)))
        return earlier

    def recall(self, pose: Pose) -> np.ndarray:
        """(N, 3) vehicle-frame points (at ``pose``) of every frame held, aged by nothing: for a
        frame without a scan time (no scans), which neither drops nor adds a frame."""
        if not self._frames:
            return np.zeros((0, 3))
        return pose.to_vehicle(np.concatenate([p for _, p in self._frames]))
