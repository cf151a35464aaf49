"""Paper T §3.1: dominant scan line (Hough), tear points and boundary points per layer.

On the road the LUX layers draw near-straight lines roughly parallel to the vehicle X axis. Per
layer we find the dominant line with a Hough transform over XY, keep the points near it, call an
adjacent pair of those points farther apart than a threshold a *tear*, and walk in from each end:
the first point followed by ``n`` tear-free links is the segment end, a boundary point.
"""

from __future__ import annotations

import numpy as np

from negobs_gym.detector.traversable.config import TraversableConfig


def hough_lines(
    xy_m: np.ndarray, valid: np.ndarray, config: TraversableConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Dominant line of each layer, ``x cos(phi) + y sin(phi) = rho``.

    Args:
        xy_m: (layers, columns, 2) points projected on the vehicle XY plane [m].
        valid: (layers, columns) mask of usable points.
        config: Detector configuration (angle range and bin sizes).

    Returns:
        ``(phi_rad, rho_m)``, each (layers,); NaN for a layer with fewer than 2 valid points.
    """
    layers = xy_m.shape[0]
    tilt = np.radians(config.hough_max_tilt_deg)
    step = np.radians(config.hough_angle_step_deg)
    n_angles = int(np.floor(tilt / step)) * 2 + 1
    phi = np.pi / 2 + (np.arange(n_angles) - n_angles // 2) * step
    phi_out = np.full(layers, np.nan)
    rho_out = np.full(layers, np.nan)
    counts = valid.sum(axis=1)
    if not (counts >= 2).any():
        return phi_out, rho_out
    x = np.where(valid, xy_m[..., 0], 0.0)
    y = np.where(valid, xy_m[..., 1], 0.0)
    rho = x[..., None] * np.cos(phi) + y[..., None] * np.sin(phi)  # (L, C, A)
    rho_lo = rho[valid].min()
    bins = np.floor((rho - rho_lo) / config.hough_rho_step_m).astype(np.int64)
    n_bins = int(bins[valid].max()) + 1
    flat = (np.arange(layers)[:, None, None] * n_angles + np.arange(n_angles)) * n_bins + bins
    votes = np.bincount(flat[valid].ravel(), minlength=layers * n_angles * n_bins)
    votes = votes.reshape(layers, n_angles * n_bins)
    best = votes.argmax(axis=1)
    a_idx, b_idx = np.divmod(best, n_bins)
    ok = counts >= 2
    phi_out[ok] = phi[a_idx[ok]]
    rho_out[ok] = rho_lo + (b_idx[ok] + 0.5) * config.hough_rho_step_m
    return phi_out, rho_out


def line_inliers(
    xy_m: np.ndarray, valid: np.ndarray, phi_rad: np.ndarray, rho_m: np.ndarray, config: TraversableConfig
) -> np.ndarray:
    """Mask (layers, columns) of valid points within ``line_tolerance_m`` of their layer's line."""
    c = np.nan_to_num(np.cos(phi_rad))[:, None]
    s = np.nan_to_num(np.sin(phi_rad))[:, None]
    with np.errstate(invalid="ignore"):
        dist = np.abs(xy_m[..., 0] * c + xy_m[..., 1] * s - rho_m[:, None])
        return valid & np.isfinite(rho_m)[:, None] & (dist <= config.line_tolerance_m)


def segment_ends(points_xy_m: np.ndarray, config: TraversableConfig) -> tuple[np.ndarray, np.ndarray]:
    """Left and right segment ends of one layer's on-line points (in column order).

    Args:
        points_xy_m: (m, 2) on-line points of one layer, ordered by azimuth (left to right).
        config: Supplies ``tear_distance_m`` and ``clean_run_points`` (n).

    Returns:
        ``(left, right)`` (2,) points; NaN when no run of n tear-free links exists.
    """
    n = config.clean_run_points
    nan = np.full(2, np.nan)
    m = points_xy_m.shape[0]
    if m < n + 1:
        return nan, nan.copy()
    gaps = np.linalg.norm(np.diff(points_xy_m, axis=0), axis=1)
    tears = np.concatenate([[0], np.cumsum(gaps > config.tear_distance_m)])
    starts = np.flatnonzero(tears[n:] - tears[:-n] == 0)  # links i..i+n-1 tear-free
    if starts.size == 0:
        return nan, nan.copy()
    return points_xy_m[starts[0]].copy(), points_xy_m[starts[-1] + n].copy()


def boundary_points(points_vehicle_m: np.ndarray, config: TraversableConfig) -> tuple[np.ndarray, np.ndarray]:
    """Raw left/right boundary points of the boundary layers (paper T §3.1).

    Args:
        points_vehicle_m: (lasers, columns, 3) vehicle-frame points, NaN = no return.
        config: Detector configuration.

    Returns:
        ``(left, right)``, each (len(boundary_layers), 2) XY [m]; NaN rows where a layer has none.
    """
    layers = list(config.boundary_layers)
    xy = points_vehicle_m[layers, :, :2]
    valid = np.isfinite(xy).all(axis=-1)
    phi, rho = hough_lines(xy, valid, config)
    inl = line_inliers(xy, valid, phi, rho, config)
    left = np.full((len(layers), 2), np.nan)
    right = np.full((len(layers), 2), np.nan)
    for i in range(len(layers)):  # 3 layers; each layer's work is vectorized
        left[i], right[i] = segment_ends(xy[i][inl[i]], config)
    return left, right
