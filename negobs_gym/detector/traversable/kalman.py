"""Paper T §3.2: scalar Kalman filters on the boundary-point coordinates.

Each coordinate (x or y) of each boundary point (left/right x boundary layer) is its own 1-D filter
with F = H = 1 and no input (u = 0): predict ``P += Q``; update ``K = P / (P + R)``,
``x += K (z - x)``, ``P *= 1 - K``. All filters run as one vectorized array. A coordinate with no
measurement this frame (NaN) is only predicted; a filter is initialised by its first measurement.
"""

from __future__ import annotations

import numpy as np

from negobs_gym.errors import ScanError


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
        self.rejections = np.zeros(self.shape[:-1], dtype=np.int64)

    def gate_points(self, measurement: np.ndarray, gate_x_m: float, reset_after: int) -> np.ndarray:
        """Drop point measurements (..., 2) whose x innovation exceeds ``gate_x_m``.

        Not in paper T: a single frame's segment end can jump inwards (bumps, occlusion); in the
        vehicle frame a boundary's lateral position changes slowly, so such a jump is held back.
        After ``reset_after`` consecutive rejections the filter restarts from the measurement
        (the boundary really moved). y is never gated: pitch bouncing legitimately moves it.

        Returns:
            The measurement with gated points set to NaN (filters to reset are re-initialised).
        """
        z = np.array(measurement, dtype=np.float64)
        innovation = np.abs(z[..., 0] - self.state[..., 0])
        far = np.isfinite(innovation) & (innovation > gate_x_m)
        self.rejections = np.where(
            far, self.rejections + 1, np.where(np.isfinite(z[..., 0]), 0, self.rejections)
        )
        restart = far & (self.rejections >= reset_after)
        self.state[restart] = np.nan
        self.variance[restart] = np.inf
        self.rejections[restart] = 0
        z[far & ~restart] = np.nan
        return z

    def carry_points(self, predicted: np.ndarray) -> None:
        """Replace the point estimates (state's last axis = (x, y)) by a motion model's prediction
        of them (not in paper T, whose F = I). A motion mixes a point's coordinates, so each takes
        the larger of the point's two variances; NaN predictions leave the filters uninitialised.
        """
        z = np.asarray(predicted, dtype=np.float64)
        if self.shape[-1] != 2 or z.shape != self.shape:
            raise ScanError(f"carry_points needs (..., 2) points of shape {self.shape}, got {z.shape}")
        self.state = z.copy()
        self.variance = np.where(
            np.isfinite(z), np.repeat(self.variance.max(axis=-1, keepdims=True), 2, axis=-1), np.inf
        )

    def update(self, measurement: np.ndarray) -> np.ndarray:
        """One predict + update step; returns a copy of the estimates (NaN = never measured).

        Args:
            measurement: Array of ``shape``; NaN where a coordinate was not measured.
        """
        z = np.asarray(measurement, dtype=np.float64)
        if z.shape != self.shape:
            raise ScanError(f"measurement shape {z.shape} != filter shape {self.shape}")
        seen = np.isfinite(z)
        fresh = seen & ~np.isfinite(self.state)
        # First measurement initialises the state with variance R.
        self.state = np.where(fresh, z, self.state)
        self.variance = np.where(fresh, self.r, self.variance + self.q)
        upd = seen & ~fresh
        gain = np.zeros(self.shape)
        gain[upd] = self.variance[upd] / (self.variance[upd] + self.r)
        # where upd the state is finite (seen before): elsewhere the NaN difference is discarded
        innovation = np.where(upd, z - self.state, 0.0)
        self.state = self.state + gain * innovation
        self.variance = self.variance * (1.0 - gain)
        return self.state.copy()
