"""Triangle meshes of the ray-cast scene: a PyBullet-style heightfield and collision primitives.

Pure numpy. Every function returns ``(vertices, triangles)``: float64 (V, 3) vertices and int32
(F, 3) vertex indices. Curved primitives are tessellated with their vertices ON the true surface,
so the mesh lies inside it by at most ``r (1 - cos(pi / segments))``; :func:`segments_for` picks the
segment count for a chord error.
"""

from __future__ import annotations

import math

import numpy as np

from negobs_gym.errors import ConfigError
from negobs_gym.sim.types import HeightField

Mesh = tuple[np.ndarray, np.ndarray]


def heightfield_mesh(heightfield: HeightField, local_origin_m: np.ndarray) -> Mesh:
    """Triangulate a heightfield exactly as Bullet's ``btHeightfieldTerrainShape`` does.

    Bullet (no flip, no diamond, no zig-zag subdivision: PyBullet's defaults) splits the quad of
    samples (i, j)..(i+1, j+1) along the diagonal from (i+1, j) to (i, j+1) in every cell; the
    tests check this against PyBullet's own ray hits. Vertices are relative to ``local_origin_m``
    (keep float32 coordinates small).
    """
    h = np.asarray(heightfield.heights_m, dtype=np.float64)
    if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2:
        raise ConfigError("heightfield", f"needs at least 2 x 2 samples, got shape {h.shape}")
    if not np.isfinite(h).all():
        raise ConfigError("heightfield", "heights contain NaN or inf")
    ny, nx = h.shape
    res = float(heightfield.resolution_m)
    o = np.asarray(local_origin_m, dtype=np.float64)
    xs = heightfield.origin_m[0] + res * np.arange(nx) - o[0]
    ys = heightfield.origin_m[1] + res * np.arange(ny) - o[1]
    gx, gy = np.meshgrid(xs, ys)
    vertices = np.stack([gx, gy, h - o[2]], axis=-1).reshape(-1, 3)
    idx = np.arange(ny * nx, dtype=np.int64).reshape(ny, nx)
    v00, v10 = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()  # (i, j), (i+1, j)
    v01, v11 = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()  # (i, j+1), (i+1, j+1)
    tris = np.concatenate([np.stack([v00, v10, v01], axis=1), np.stack([v10, v11, v01], axis=1)])
    return vertices, tris.astype(np.int32)


def box_mesh(half_extents_m: np.ndarray) -> Mesh:
    """12 triangles of an axis-aligned box centred on the origin."""
    hx, hy, hz = np.asarray(half_extents_m, dtype=np.float64)
    corners = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    # corner index = 4 * (sx > 0) + 2 * (sy > 0) + (sz > 0)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [(a, b, c) for a, b, c, _ in quads] + [(a, c, d) for a, _, c, d in quads]
    return corners, np.asarray(tris, dtype=np.int32)


def segments_for(
    radius_m: float, chord_error_m: float, min_segments: int = 8, max_segments: int = 1024
) -> int:
    """Segments around a circle of ``radius_m`` so that no chord lies more than ``chord_error_m``
    inside it: ``r (1 - cos(pi / n)) <= e``."""
    if not (radius_m > 0 and chord_error_m > 0):
        raise ConfigError("radius_m", f"radius and chord error must be > 0, got {radius_m}, {chord_error_m}")
    if chord_error_m >= radius_m:
        return min_segments
    n = math.ceil(math.pi / math.acos(1.0 - chord_error_m / radius_m))
    return int(min(max(n, min_segments), max_segments))


def _ring(radius_m: float, z_m: float, segments: int) -> np.ndarray:
    t = 2.0 * np.pi * np.arange(segments) / segments
    return np.stack([radius_m * np.cos(t), radius_m * np.sin(t), np.full(segments, z_m)], axis=1)


def _stack_rings(rings: list[np.ndarray], bottom: np.ndarray | None, top: np.ndarray | None) -> Mesh:
    """Mesh of closed rings of equal size stacked along z, capped by optional pole points."""
    n = rings[0].shape[0]
    k = np.arange(n)
    kn = (k + 1) % n
    verts = [np.concatenate(rings)]
    tris = []
    for r in range(len(rings) - 1):
        a, b = r * n + k, r * n + kn
        c, d = (r + 1) * n + k, (r + 1) * n + kn
        tris += [np.stack([a, b, d], axis=1), np.stack([a, d, c], axis=1)]
    base = len(rings) * n
    if bottom is not None:
        verts.append(bottom[None])
        tris.append(np.stack([np.full(n, base), kn, k], axis=1))
        base += 1
    if top is not None:
        verts.append(top[None])
        last = (len(rings) - 1) * n
        tris.append(np.stack([np.full(n, base), last + k, last + kn], axis=1))
    return np.concatenate(verts), np.concatenate(tris).astype(np.int32)


def cylinder_mesh(radius_m: float, half_height_m: float, segments: int) -> Mesh:
    """Closed cylinder along local z, centred on the origin (Bullet's GEOM_CYLINDER)."""
    rings = [_ring(radius_m, -half_height_m, segments), _ring(radius_m, half_height_m, segments)]
    return _stack_rings(rings, np.array([0.0, 0.0, -half_height_m]), np.array([0.0, 0.0, half_height_m]))


def capsule_mesh(radius_m: float, half_height_m: float, segments: int) -> Mesh:
    """Capsule along local z: a cylinder of half height ``half_height_m`` with hemispherical caps."""
    n_lat = max(segments // 4, 2)
    lat = np.linspace(0.0, 0.5 * np.pi, n_lat + 1)[1:-1]  # strictly between equator and pole
    lower = [_ring(radius_m * np.cos(a), -half_height_m - radius_m * np.sin(a), segments) for a in lat[::-1]]
    upper = [_ring(radius_m * np.cos(a), half_height_m + radius_m * np.sin(a), segments) for a in lat]
    equator = [_ring(radius_m, -half_height_m, segments)]
    if half_height_m > 0.0:
        equator.append(_ring(radius_m, half_height_m, segments))
    rings = lower + equator + upper
    return _stack_rings(
        rings,
        np.array([0.0, 0.0, -half_height_m - radius_m]),
        np.array([0.0, 0.0, half_height_m + radius_m]),
    )


def sphere_mesh(radius_m: float, segments: int) -> Mesh:
    """UV sphere centred on the origin (a capsule with zero cylinder length)."""
    return capsule_mesh(radius_m, 0.0, segments)


def convex_hull_mesh(points_m: np.ndarray) -> Mesh:
    """Triangles of the convex hull of (N, 3) points (Bullet's convex GEOM_MESH)."""
    from scipy.spatial import ConvexHull

    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    if pts.shape[0] < 4 or not np.isfinite(pts).all():
        raise ConfigError("mesh", f"a convex mesh needs >= 4 finite vertices, got {pts.shape[0]}")
    hull = ConvexHull(pts)
    return pts, hull.simplices.astype(np.int32)


def transform_mesh(mesh: Mesh, rotation: np.ndarray, translation_m: np.ndarray) -> Mesh:
    """Mesh with vertices mapped by ``R v + t``."""
    v, f = mesh
    return v @ np.asarray(rotation).T + np.asarray(translation_m), f


def merge_meshes(meshes: list[Mesh]) -> Mesh:
    """One mesh from many (indices offset); an empty list gives an empty mesh."""
    if not meshes:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32)
    offsets = np.cumsum([0] + [m[0].shape[0] for m in meshes[:-1]])
    v = np.concatenate([m[0] for m in meshes])
    f = np.concatenate([m[1] + off for m, off in zip(meshes, offsets, strict=True)])
    return v, f.astype(np.int32)
