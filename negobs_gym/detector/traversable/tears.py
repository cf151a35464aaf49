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


def refine_lines(xy_m: np.ndarray, inliers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total-least-squares refit of each layer's line to its Hough inliers (NaN if < 2).

    The Hough peak sits on the densest stretch of a sagging scan line (a road crown, paper T
    Fig. 10); the refit centres the line on all of its points so both ends stay within tolerance.
    """
    layers = xy_m.shape[0]
    phi = np.full(layers, np.nan)
    rho = np.full(layers, np.nan)
    w = inliers.astype(np.float64)
    count = w.sum(axis=1)
    ok = count >= 2
    if not ok.any():
        return phi, rho
    pts = np.where(inliers[..., None], xy_m, 0.0)
    mean = pts.sum(axis=1) / np.maximum(count, 1)[:, None]
    d = np.where(inliers[..., None], xy_m - mean[:, None, :], 0.0)
    sxx = (d[..., 0] ** 2).sum(axis=1)
    syy = (d[..., 1] ** 2).sum(axis=1)
    sxy = (d[..., 0] * d[..., 1]).sum(axis=1)
    # Normal of the best-fit line: direction of least spread.
    angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy) + np.pi / 2
    phi[ok] = angle[ok]
    rho[ok] = mean[ok, 0] * np.cos(angle[ok]) + mean[ok, 1] * np.sin(angle[ok])
    return phi, rho


def line_inliers(
    xy_m: np.ndarray, valid: np.ndarray, phi_rad: np.ndarray, rho_m: np.ndarray, config: TraversableConfig
) -> np.ndarray:
    """Mask (layers, columns) of valid points within ``line_tolerance_m`` of their layer's line."""
    c = np.nan_to_num(np.cos(phi_rad))[:, None]
    s = np.nan_to_num(np.sin(phi_rad))[:, None]
    with np.errstate(invalid="ignore"):
        dist = np.abs(xy_m[..., 0] * c + xy_m[..., 1] * s - rho_m[:, None])
        return valid & np.isfinite(rho_m)[:, None] & (dist <= config.line_tolerance_m)


def segment_end_indices(points_xy_m: np.ndarray, config: TraversableConfig) -> tuple[int, int] | None:
    """Indices of the left and right segment ends of one layer's on-line points (column order).

    Walking in from each end, the end is the first point followed by ``clean_run_points`` (n)
    links no longer than ``tear_distance_m``. ``None`` when no such run exists.
    """
    n = config.clean_run_points
    if points_xy_m.shape[0] < n + 1:
        return None
    gaps = np.linalg.norm(np.diff(points_xy_m, axis=0), axis=1)
    tears = np.concatenate([[0], np.cumsum(gaps > config.tear_distance_m)])
    starts = np.flatnonzero(tears[n:] - tears[:-n] == 0)  # links i..i+n-1 tear-free
    if starts.size == 0:
        return None
    return int(starts[0]), int(starts[-1] + n)


def segment_ends(points_xy_m: np.ndarray, config: TraversableConfig) -> tuple[np.ndarray, np.ndarray]:
    """Left and right segment ends (2,) of one layer's on-line points; NaN when there are none."""
    ends = segment_end_indices(points_xy_m, config)
    if ends is None:
        return np.full(2, np.nan), np.full(2, np.nan)
    return points_xy_m[ends[0]].copy(), points_xy_m[ends[1]].copy()


def _occluded(ranges_m: np.ndarray, column: int, outward: int, jump_m: float) -> bool:
    """True when the first return outwards of ``column`` (``outward`` = -1 left, +1 right) is
    at least ``jump_m`` nearer than the return at ``column``."""
    beyond = ranges_m[column + 1 :] if outward > 0 else ranges_m[:column][::-1]
    finite = beyond[np.isfinite(beyond)]
    return bool(finite.size and finite[0] < ranges_m[column] - jump_m)


def boundary_points(
    points_vehicle_m: np.ndarray, ranges_m: np.ndarray, config: TraversableConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Raw left/right boundary points of the boundary layers (paper T §3.1).

    A segment end whose next return outwards is much nearer (``occlusion_jump_m``) ends at an
    occluding obstacle, not at the road edge (paper T Fig. 12 discusses this error); it is
    reported as missing so that the Kalman filter keeps its previous estimate instead.

    Args:
        points_vehicle_m: (lasers, columns, 3) vehicle-frame points, NaN = no return.
        ranges_m: (lasers, columns) ranges of the same scan, NaN = no return.
        config: Detector configuration.

    Returns:
        ``(left, right)``, each (len(boundary_layers), 2) XY [m]; NaN rows where a layer has none.
    """
    layers = list(config.boundary_layers)
    xy = points_vehicle_m[layers, :, :2]
    valid = np.isfinite(xy).all(axis=-1)
    stride = config.hough_column_stride
    phi, rho = hough_lines(xy[:, ::stride], valid[:, ::stride], config)
    inl = line_inliers(xy, valid, phi, rho, config)
    phi, rho = refine_lines(xy, inl)
    inl = line_inliers(xy, valid, phi, rho, config)
    left = np.full((len(layers), 2), np.nan)
    right = np.full((len(layers), 2), np.nan)
    for i, layer in enumerate(layers):  # 3 layers; each layer's work is vectorized
        cols = np.flatnonzero(inl[i])
        ends = segment_end_indices(xy[i, cols], config)
        if ends is None:
            continue
        lc, rc = cols[ends[0]], cols[ends[1]]
        if not _occluded(ranges_m[layer], lc, -1, config.occlusion_jump_m):
            left[i] = xy[i, lc]
        if not _occluded(ranges_m[layer], rc, +1, config.occlusion_jump_m):
            right[i] = xy[i, rc]
    return left, right
