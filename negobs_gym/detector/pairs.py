"""Negative-obstacle feature point pairs (paper N §3): the record passed from the per-sensor
feature extractors to the multi-frame fusion.

A pair (A, B) spans the gap that a negative obstacle leaves in a scan line: ``A`` is the last ground
point on the near side, ``B`` the first point on the far side (the back wall / far rim). ``C`` is the
point after ``B`` on the same ray direction (used by the Eq. 14 back-wall test).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class FeaturePairs:
    """A batch of feature point pairs of one sensor in one frame, in the vehicle frame.

    Attributes:
        sensor: Name of the sensor that produced them (e.g. ``"hdl64"``).
        a_m: (n, 3) near-side points A [m].
        b_m: (n, 3) far-side points B [m].
        c_m: (n, 3) points C beyond B [m] (NaN rows allowed where C is unknown).
    """

    sensor: str
    a_m: np.ndarray
    b_m: np.ndarray
    c_m: np.ndarray

    def __post_init__(self) -> None:
        for name in ("a_m", "b_m", "c_m"):
            arr = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1, 3)
            object.__setattr__(self, name, arr)
        n = self.a_m.shape[0]
        if self.b_m.shape[0] != n or self.c_m.shape[0] != n:
            raise ValueError(
                f"{self.sensor}: A, B, C must have the same number of rows, got "
                f"{self.a_m.shape[0]}, {self.b_m.shape[0]}, {self.c_m.shape[0]}"
            )

    def __len__(self) -> int:
        return int(self.a_m.shape[0])

    @classmethod
    def empty(cls, sensor: str) -> FeaturePairs:
        """No pairs."""
        z = np.empty((0, 3))
        return cls(sensor, z, z, z)
