"""Paper T §3.2: scalar Kalman filters on the boundary-point coordinates.

Each coordinate (x or y) of each boundary point (left/right x boundary layer) is its own 1-D filter
with F = H = 1 and no input (u = 0): predict ``P += Q``; update ``K = P / (P + R)``,
``x += K (z - x)``, ``P *= 1 - K``. All filters run as one vectorized array. A coordinate with no
measurement this frame (NaN) is only predicted; a filter is initialised by its first measurement.
"""

from __future__ import annotations

import numpy as np


class BoundaryKalman:
    """A bank of independent scalar Kalman filters (F = H = I, u = 0)."""

    def __init__(self, shape: tuple[int, ...], measurement_var: float, process_var: float) -> None:
        """Create filters of the given array shape with noise variances R and Q [m^2]."""
        self.shape = tuple(shape)
        self.r = float(measurement_var)
        self.q = float(process_var)
        self.reset()

    def reset(self) -> None:
        """Forget every estimate (all filters uninitialised)."""
        self.state = np.full(self.shape, np.nan)
        self.variance = np.full(self.shape, np.inf)

    def update(self, measurement: np.ndarray) -> np.ndarray:
        """One predict + update step; returns a copy of the estimates (NaN = never measured).

        Args:
            measurement: Array of ``shape``; NaN where a coordinate was not measured.
        """
        z = np.asarray(measurement, dtype=np.float64)
        if z.shape != self.shape:
            raise ValueError(f"measurement shape {z.shape} != filter shape {self.shape}")
        seen = np.isfinite(z)
        fresh = seen & ~np.isfinite(self.state)
        # First measurement initialises the state with variance R.
        self.state = np.where(fresh, z, self.state)
        self.variance = np.where(fresh, self.r, self.variance + self.q)
        upd = seen & ~fresh
        gain = np.zeros(self.shape)
        gain[upd] = self.variance[upd] / (self.variance[upd] + self.r)
        innovation = np.where(upd, z - np.nan_to_num(self.state), 0.0)
        self.state = self.state + gain * innovation
        self.variance = self.variance * (1.0 - gain)
        return self.state.copy()
