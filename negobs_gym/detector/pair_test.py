"""Feature-pair test of paper N Eq. 11-14 (shared by the HDL-64 and HDL-32 extractors)."""

from __future__ import annotations

import numpy as np

from negobs_gym.detector.config import PairTestConfig


def pair_test(
    a_m: np.ndarray,
    b_m: np.ndarray,
    c_m: np.ndarray,
    sensor_m: np.ndarray,
    height_m: float,
    config: PairTestConfig,
) -> np.ndarray:
    """Boolean mask of (A, B, C) triples that pass Eq. 14.

    Eq. 11-13: ``d_AB``, ``d_BC`` horizontal distances, ``dz_BC = z_C - z_B``. Eq. 14:
    ``d_AB >= w_min``, ``d_AB >= gamma1 d_BC``, ``dz_BC >= gamma2 h d_AB / y_A``. Paper N's
    ``y_A`` is A's forward distance from a forward-looking sensor; here it is A's horizontal
    distance from the sensor (identical straight ahead, and valid for side sensors and any
    azimuth). Rows with NaN (e.g. no C found) fail.

    Args:
        a_m, b_m, c_m: (n, 3) vehicle-frame points.
        sensor_m: (3,) sensor origin in the vehicle frame, or (n, 3) one per triple (a deskewed
            scan's origin when it fired each B, :meth:`StructuredScan.origins_vehicle`).
        height_m: Sensor height above the ground [m].
        config: Eq. 14 thresholds.
    """
    a = np.asarray(a_m, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(b_m, dtype=np.float64).reshape(-1, 3)
    c = np.asarray(c_m, dtype=np.float64).reshape(-1, 3)
    s = np.asarray(sensor_m, dtype=np.float64).reshape(-1, 3)
    d_ab = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])  # Eq. 11
    d_bc = np.hypot(b[:, 0] - c[:, 0], b[:, 1] - c[:, 1])  # Eq. 12
    dz_bc = c[:, 2] - b[:, 2]  # Eq. 13
    y_a = np.hypot(a[:, 0] - s[:, 0], a[:, 1] - s[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (
            (d_ab >= config.w_min_m)
            & (d_ab >= config.gamma1 * d_bc)
            & (dz_bc >= config.gamma2 * height_m * d_ab / y_a)
            & (y_a > 0)
        )
    return ok & np.isfinite(d_ab) & np.isfinite(d_bc) & np.isfinite(dz_bc)
