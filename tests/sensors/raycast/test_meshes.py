import math

import numpy as np
import pybullet as p
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.sensors.raycast.meshes import (
    box_mesh,
    capsule_mesh,
    convex_hull_mesh,
    cylinder_mesh,
    heightfield_mesh,
    merge_meshes,
    segments_for,
    sphere_mesh,
    transform_mesh,
)
from negobs_gym.sim.types import HeightField


def _closed(mesh) -> bool:
    """Every undirected edge is shared by exactly two triangles (a watertight surface)."""
    _, f = mesh
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return bool(np.all(counts == 2))


def _ray_z(mesh, xy):
    """Z of the first hit of vertical rays (down from z = 100) on a mesh; brute force over triangles."""
    v, f = mesh
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    out = np.full(len(xy), np.nan)
    for k, (x, y) in enumerate(xy):  # test helper: few rays
        with np.errstate(divide="ignore", invalid="ignore"):  # vertical faces: d0 = 0, never "inside"
            u, w, z = _bary(a, b, c, x, y)
            inside = (u >= -1e-9) & (w >= -1e-9) & (u + w <= 1 + 1e-9)
        if inside.any():
            out[k] = z[inside].max()
    return out


def _bary(a, b, c, x, y):
    d0 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    u = ((x - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (y - a[:, 1])) / d0
    w = ((b[:, 0] - a[:, 0]) * (y - a[:, 1]) - (x - a[:, 0]) * (b[:, 1] - a[:, 1])) / d0
    z = a[:, 2] + u * (b[:, 2] - a[:, 2]) + w * (c[:, 2] - a[:, 2])
    return u, w, z


def test_heightfield_diagonal_matches_pybullet():
    rng = np.random.default_rng(0)
    h = rng.uniform(-0.5, 0.5, size=(6, 7)).astype(np.float32)  # (ny, nx)
    hf = HeightField(heights_m=h, resolution_m=0.5, origin_m=(1.0, -2.0))
    c = p.connect(p.DIRECT)
    try:
        ny, nx = h.shape
        shape = p.createCollisionShape(
            p.GEOM_HEIGHTFIELD,
            meshScale=[0.5, 0.5, 1.0],
            heightfieldData=h.ravel().tolist(),
            numHeightfieldRows=nx,
            numHeightfieldColumns=ny,
            physicsClientId=c,
        )
        base = [1.0 + 0.25 * (nx - 1), -2.0 + 0.25 * (ny - 1), 0.5 * (float(h.min()) + float(h.max()))]
        p.createMultiBody(0, shape, basePosition=base, physicsClientId=c)
        xy = np.column_stack([rng.uniform(1.05, 3.95, 300), rng.uniform(-1.95, 0.45, 300)])
        hits = p.rayTestBatch(
            np.column_stack([xy, np.full(300, 5.0)]),
            np.column_stack([xy, np.full(300, -5.0)]),
            physicsClientId=c,
        )
        z_bullet = np.array([r[3][2] for r in hits])
    finally:
        p.disconnect(c)
    mesh = heightfield_mesh(hf, np.zeros(3))
    np.testing.assert_allclose(_ray_z(mesh, xy), z_bullet, atol=1e-4)
    # the other diagonal would be wrong by far more than 1 cm somewhere: the test can fail
    v, f = mesh
    n = f.shape[0] // 2
    v00, v10, v01 = f[:n, 0], f[:n, 1], f[:n, 2]
    v11 = f[n:, 1]
    other = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    assert np.nanmax(np.abs(_ray_z((v, other), xy) - z_bullet)) > 0.05


def test_heightfield_bad_input():
    with pytest.raises(ConfigError, match="heightfield"):
        heightfield_mesh(HeightField(np.zeros((1, 5), np.float32), 0.1, (0.0, 0.0)), np.zeros(3))
    with pytest.raises(ConfigError, match="heightfield"):
        heightfield_mesh(HeightField(np.full((3, 3), np.nan, np.float32), 0.1, (0.0, 0.0)), np.zeros(3))


@pytest.mark.parametrize(
    ("mesh", "radius"),
    [
        (box_mesh(np.array([1.0, 2.0, 0.5])), None),
        (cylinder_mesh(0.3, 0.85, 40), 0.3),
        (capsule_mesh(0.2, 0.5, 32), 0.2),
        (sphere_mesh(0.4, 48), 0.4),
    ],
)
def test_primitives_closed_and_on_surface(mesh, radius):
    v, f = mesh
    assert _closed(mesh)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    assert np.all(area > 1e-9)  # no degenerate triangles
    if radius is not None:  # side/sphere vertices lie on the true surface
        r_xy = np.hypot(v[:, 0], v[:, 1])
        on_axis = r_xy < 1e-12
        assert np.all((np.abs(r_xy - radius) < 1e-9) | on_axis | (r_xy < radius))


def test_box_hit_exact():
    z = _ray_z(box_mesh(np.array([1.0, 2.0, 0.5])), np.array([[0.3, -1.9], [0.99, 1.99], [1.01, 0.0]]))
    np.testing.assert_allclose(z[:2], 0.5)
    assert np.isnan(z[2])


def test_segments_for_chord_error():
    n = segments_for(0.4, 1e-4)
    assert 0.4 * (1 - math.cos(math.pi / n)) <= 1e-4 < 0.4 * (1 - math.cos(math.pi / (n - 1)))
    assert segments_for(0.01, 1e-4) >= 8
    with pytest.raises(ConfigError):
        segments_for(0.0, 1e-4)


def test_convex_hull_and_merge():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.1, 0.1, 0.1]], float)
    hull = convex_hull_mesh(pts)
    assert hull[1].shape == (4, 3) and _closed(hull)
    moved = transform_mesh(hull, np.eye(3), np.array([5.0, 0, 0]))
    v, f = merge_meshes([hull, moved])
    assert v.shape == (10, 3) and f.shape == (8, 3) and f[4:].min() == 5
    with pytest.raises(ConfigError, match="mesh"):
        convex_hull_mesh(pts[:3])
    assert merge_meshes([])[1].shape == (0, 3)
