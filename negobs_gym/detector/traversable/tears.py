"""Paper T §3.1: dominant scan line (Hough), tear points and boundary points per layer.

On the road the LUX layers draw near-straight lines roughly parallel to the vehicle X axis. Per
layer we find the dominant line with a Hough transform over XY, refit the scan line as a parabola
in that line's frame (the layers are really conics, see :func:`refine_curves`), keep the points
near it, call an adjacent pair of those points farther apart than a threshold a *tear*, and walk
in from each end: the first point followed by ``n`` tear-free links is the segment end, a
boundary point, unless no return lies beyond it (the scan line leaves the field of view) or the
return beyond it is much nearer (an occluder).
"""

from __future__ import annotations

import functools

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
    phi, trig = _hough_angles(config.hough_max_tilt_deg, config.hough_angle_step_deg)
    n_angles = phi.size
    phi_out = np.full(layers, np.nan)
    rho_out = np.full(layers, np.nan)
    counts = valid.sum(axis=1)
    if not (counts >= 2).any():
        return phi_out, rho_out
    layer_of, column_of = np.nonzero(valid)
    rho = xy_m[layer_of, column_of] @ trig  # (N valid points, A)
    rho_lo = rho.min()
    shifted = rho - rho_lo
    shifted /= config.hough_rho_step_m
    bins = shifted.astype(np.int64)  # >= 0: floor
    n_bins = int(bins.max()) + 1
    bins += np.arange(0, n_angles * n_bins, n_bins)  # vote index: (layer, angle, bin), in place
    bins += (layer_of * (n_angles * n_bins))[:, None]
    votes = np.bincount(bins.ravel(), minlength=layers * n_angles * n_bins)
    votes = votes.reshape(layers, n_angles * n_bins)
    best = votes.argmax(axis=1)
    a_idx, b_idx = np.divmod(best, n_bins)
    ok = counts >= 2
    phi_out[ok] = phi[a_idx[ok]]
    rho_out[ok] = rho_lo + (b_idx[ok] + 0.5) * config.hough_rho_step_m
    return phi_out, rho_out


@functools.lru_cache(maxsize=8)
def _hough_angles(max_tilt_deg: float, step_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """The Hough normal angles phi (A,) about +Y's normal (pi/2) and their (cos, sin) (2, A)."""
    tilt = np.radians(max_tilt_deg)
    step = np.radians(step_deg)
    n_angles = int(np.floor(tilt / step)) * 2 + 1
    phi = np.pi / 2 + (np.arange(n_angles) - n_angles // 2) * step
    phi.flags.writeable = False
    trig = np.stack([np.cos(phi), np.sin(phi)])
    trig.flags.writeable = False
    return phi, trig


def line_inliers(
    xy_m: np.ndarray, valid: np.ndarray, phi_rad: np.ndarray, rho_m: np.ndarray, config: TraversableConfig
) -> np.ndarray:
    """Mask (layers, columns) of valid points within ``line_tolerance_m`` of their layer's line."""
    c = np.nan_to_num(np.cos(phi_rad))[:, None]
    s = np.nan_to_num(np.sin(phi_rad))[:, None]
    with np.errstate(invalid="ignore"):
        dist = np.abs(xy_m[..., 0] * c + xy_m[..., 1] * s - rho_m[:, None])
        return valid & np.isfinite(rho_m)[:, None] & (dist <= config.line_tolerance_m)


def line_frame(xy_m: np.ndarray, phi_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates of points (layers, columns, 2) along (u) and across (v) their layer's line.

    ``v = x cos(phi) + y sin(phi)`` is the Hough normal coordinate (``rho`` on the line) and
    ``u = x sin(phi) - y cos(phi)`` runs along the line; NaN points and layers give NaN.
    """
    c = np.cos(phi_rad)[:, None]
    s = np.sin(phi_rad)[:, None]
    x = xy_m[..., 0]
    y = xy_m[..., 1]
    return x * s - y * c, x * c + y * s


def refine_curves(
    u_m: np.ndarray, v_m: np.ndarray, inliers: np.ndarray, config: TraversableConfig
) -> np.ndarray:
    """Least-squares parabola ``v = c0 + c1 u + c2 u^2`` of each layer in its Hough line's frame.

    Not in paper T, which keeps the Hough line: a LUX pitched down 5 deg draws conics on flat
    ground, not lines. Over 110 deg the ends of the lowest layer bend ~0.5 m towards the sensor
    off the best straight line and those of the upper layers ~0.4 m away from it (the pitch adds
    less depression at wide azimuth). A straight tolerance band then ends the lowest layer early
    and lets the upper layers climb a gentle bank, so the boundary points of one side lean
    outwards with distance. The parabola follows the conic (and a road crown, Fig. 10) to within
    a few centimetres, so the band means the same thing at every azimuth.

    Args:
        u_m, v_m: (layers, columns) coordinates from :func:`line_frame`.
        inliers: (layers, columns) points to fit.
        config: Detector configuration (``curve_min_points``).

    Returns:
        (layers, 3) coefficients ``(c0, c1, c2)``; NaN rows for layers with fewer than
        ``curve_min_points`` usable inliers or whose inliers do not span a parabola.
    """
    layers = u_m.shape[0]
    coef = np.full((layers, 3), np.nan)
    use = inliers & np.isfinite(u_m) & np.isfinite(v_m)
    ok = use.sum(axis=1) >= config.curve_min_points
    if not ok.any():
        return coef
    u_s = np.where(use, u_m, 0.0) / _U_SCALE_M  # keeps the normal equations well scaled
    w = use.astype(np.float64)
    # Normal equations of all layers at once from the moments sum(u^k), k = 0..4, and
    # sum(v u^k), k = 0..2, as batched matrix products (unused points have zero weight).
    # products, not **: integer powers of arrays are far slower
    powers = np.empty((*u_s.shape, 5))  # (L, C, 5)
    powers[..., 0] = 1.0
    powers[..., 1] = u_s
    u2 = np.multiply(u_s, u_s, out=powers[..., 2])
    np.multiply(u2, u_s, out=powers[..., 3])
    np.multiply(u2, u2, out=powers[..., 4])
    moments = (w[:, None, :] @ powers)[:, 0]  # (L, 5)
    ata = moments[:, _HANKEL]  # (L, 3, 3)
    atb = ((w * np.where(use, v_m, 0.0))[:, None, :] @ powers[..., :3])[:, 0]  # (L, 3)
    ok[ok] = _well_conditioned(ata[ok])
    if ok.any():
        scaled = np.linalg.solve(ata[ok], atb[ok][..., None])[..., 0]
        coef[ok] = scaled / np.array([1.0, _U_SCALE_M, _U_SCALE_M**2])
    return coef


# Along-line coordinates are divided by this before the fit (a layer spans about +-10 m).
_U_SCALE_M = 10.0
# Index of the moments sum(u^k) in the normal equations' Hankel matrix, k = i + j.
_HANKEL = np.add.outer(np.arange(3), np.arange(3))
# Normal equations worse conditioned than this have no unique parabola (points at one u).
_MAX_CONDITION = 1e10
# A condition-number bound this far under _MAX_CONDITION needs no SVD (_well_conditioned).
_SURE_CONDITION = 1e8


def _well_conditioned(ata: np.ndarray) -> np.ndarray:
    """Whether each normal-equation matrix (m, 3, 3) has a 2-norm condition number (as
    np.linalg.cond gives it) below ``_MAX_CONDITION``.

    These are Gram matrices (symmetric, positive semi-definite): with eigenvalues l1 >= l2 >= l3,
    l1 <= trace and l3 >= det / (l1 l2) >= det / trace^2, so cond <= trace^3 / det. Where that
    bound is below ``_SURE_CONDITION`` (100x under the limit, far beyond the rounding of det and
    of the SVD) the answer is yes without an SVD; the rest take np.linalg.cond's SVD.
    """
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = ata.reshape(-1, 9).T
    det = a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20) + a02 * (a10 * a21 - a11 * a20)
    trace = a00 + a11 + a22
    with np.errstate(all="ignore"):
        good = (det > 0.0) & (trace * trace * trace < _SURE_CONDITION * det)
    if not good.all():
        singular = np.linalg.svd(ata[~good], compute_uv=False)
        with np.errstate(all="ignore"):  # NaN and inf both fail the test
            good[~good] = singular[:, 0] / singular[:, -1] < _MAX_CONDITION
    return good


def curve_inliers(
    u_m: np.ndarray, v_m: np.ndarray, valid: np.ndarray, coef: np.ndarray, config: TraversableConfig
) -> np.ndarray:
    """Mask (layers, columns) of valid points within ``line_tolerance_m`` (along v) of the curve."""
    with np.errstate(invalid="ignore"):
        fit = coef[:, 0:1] + (coef[:, 1:2] + coef[:, 2:3] * u_m) * u_m
        return valid & np.isfinite(coef).all(axis=1)[:, None] & (np.abs(v_m - fit) <= config.line_tolerance_m)


def segment_end_indices(points_xy_m: np.ndarray, config: TraversableConfig) -> tuple[int, int] | None:
    """Indices of the left and right segment ends of one layer's on-line points (column order).

    Walking in from each end, the end is the first point followed by ``clean_run_points`` (n)
    links no longer than ``tear_distance_m``. ``None`` when no such run exists.
    """
    pts = np.asarray(points_xy_m, dtype=np.float64)
    return _layer_segment_ends(pts[None], np.ones((1, pts.shape[0]), dtype=bool), config)[0]


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


def _cut_by_fov(valid: np.ndarray, column: int, outward: int) -> bool:
    """True when no return lies outwards of ``column`` (``outward`` = -1 left, +1 right)."""
    beyond = valid[column + 1 :] if outward > 0 else valid[:column]
    return not bool(beyond.any())


def boundary_points(
    points_vehicle_m: np.ndarray, ranges_m: np.ndarray, config: TraversableConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Raw left/right boundary points of the boundary layers (paper T §3.1).

    A boundary point is a segment end *at a tear*. Two kinds of segment end are not, and are
    reported as missing so that the Kalman filter keeps its previous estimate instead:

    - an end with no return outwards of it: no tear ends the segment there, the scan line
      leaves the field of view (or the sensor's range) while still on the road, so the road edge
      lies beyond what the layer sees. Taking that end as the edge puts the boundary point on the
      FOV's edge ray; where the ground rises to one side (or the road is wider than the FOV at
      the layer's range) the near layers are cut there and the fitted boundary leans along that
      ray (a 55 deg edge ray is at x = -4.5 m where it is 3.2 m ahead of the sensor);
    - an end whose next return outwards is much nearer (``occlusion_jump_m``): it ends at an
      occluding obstacle, not at the road edge (paper T Fig. 12 discusses this error).

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
    u, v = line_frame(xy, phi)
    # line_inliers on the v already at hand (v - rho is the distance to the Hough line)
    with np.errstate(invalid="ignore"):
        inl = valid & np.isfinite(rho)[:, None] & (np.abs(v - rho[:, None]) <= config.line_tolerance_m)
    for _ in range(config.curve_refits):
        coef = refine_curves(u, v, inl, config)
        # A layer too sparse for a parabola keeps its Hough line's inliers.
        fitted = np.isfinite(coef).all(axis=1)[:, None]
        refit = np.where(fitted, curve_inliers(u, v, valid, coef, config), inl)
        converged = np.array_equal(refit, inl)  # a further refit would fit the same points again
        inl = refit
        if converged:
            break
    left = np.full((len(layers), 2), np.nan)
    right = np.full((len(layers), 2), np.nan)
    for i, ends in enumerate(_layer_segment_ends(xy, inl, config)):
        if ends is None:
            continue
        layer = layers[i]
        lc, rc = ends
        if not (_cut_by_fov(valid[i], lc, -1) or _occluded(ranges_m[layer], lc, -1, config.occlusion_jump_m)):
            left[i] = xy[i, lc]
        if not (_cut_by_fov(valid[i], rc, +1) or _occluded(ranges_m[layer], rc, +1, config.occlusion_jump_m)):
            right[i] = xy[i, rc]
    return left, right


def _layer_segment_ends(
    xy_m: np.ndarray, inliers: np.ndarray, config: TraversableConfig
) -> list[tuple[int, int] | None]:
    """:func:`segment_end_indices` of every layer's inliers at once, as columns of ``xy_m``.

    The layers' inliers are chained in one array, each link between two layers counted as a
    tear, so that no tear-free run crosses from one layer into the next.
    """
    n = config.clean_run_points
    layer_of, cols = np.nonzero(inliers)
    pts = xy_m[layer_of, cols]
    step = pts[1:] - pts[:-1]
    gaps = np.sqrt(step[:, 0] * step[:, 0] + step[:, 1] * step[:, 1])  # np.linalg.norm's rounding
    torn = (gaps > config.tear_distance_m) | (layer_of[1:] != layer_of[:-1])
    tears = np.zeros(pts.shape[0], dtype=np.int64)
    np.cumsum(torn, out=tears[1:])
    starts = np.flatnonzero(tears[n:] - tears[:-n] == 0)  # links i..i+n-1 tear-free
    start_layer = layer_of[starts]
    ends: list[tuple[int, int] | None] = []
    for i in range(xy_m.shape[0]):
        lo, hi = np.searchsorted(start_layer, (i, i + 1))
        ends.append(None if lo == hi else (int(cols[starts[lo]]), int(cols[starts[hi - 1] + n])))
    return ends
