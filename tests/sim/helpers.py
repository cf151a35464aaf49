"""Small hand-made terrains for the physics tests (fast to build, exact ground truth)."""

from __future__ import annotations

import numpy as np

from negobs_gym.sim.types import HeightField, NegativeObstacle, PositiveObstacle, Terrain, Track

RES_M = 0.1


def flat_terrain(
    length_m: float = 40.0,
    width_m: float = 12.0,
    *,
    pits: tuple[tuple[str, float, float, float, float, float], ...] = (),
    positives: tuple[PositiveObstacle, ...] = (),
    roughness_m: float = 0.0,
    seed: int = 0,
) -> Terrain:
    """A flat (or gently rough) straight track along +Y from y = 0, centred on x = 0.

    ``pits`` are ``(id, centre_x, centre_y, size_x, size_y, depth)`` rectangles carved to a flat floor.
    """
    nx = round(width_m / RES_M) + 1
    ny = round(length_m / RES_M) + 1
    origin = (-0.5 * width_m, -5.0)
    h = np.zeros((ny, nx), np.float32)
    if roughness_m > 0:
        rng = np.random.default_rng(seed)
        coarse = rng.normal(scale=roughness_m, size=(ny // 20 + 2, nx // 20 + 2))
        yy, xx = np.mgrid[0:ny, 0:nx] / 20.0
        j0, i0 = yy.astype(int), xx.astype(int)
        ty, tx = yy - j0, xx - i0
        h = (
            coarse[j0, i0] * (1 - tx) * (1 - ty)
            + coarse[j0, i0 + 1] * tx * (1 - ty)
            + coarse[j0 + 1, i0] * (1 - tx) * ty
            + coarse[j0 + 1, i0 + 1] * tx * ty
        ).astype(np.float32)
    xs = origin[0] + np.arange(nx) * RES_M
    ys = origin[1] + np.arange(ny) * RES_M
    negatives = []
    for pid, cx, cy, sx, sy, depth in pits:
        inside_x = np.abs(xs - cx) <= 0.5 * sx + 1e-6
        inside_y = np.abs(ys - cy) <= 0.5 * sy + 1e-6
        block = np.ix_(inside_y, inside_x)
        rim = float(h[block].max())
        h[block] = rim - depth
        outline = np.array(
            [
                [cx - sx / 2, cy - sy / 2],
                [cx + sx / 2, cy - sy / 2],
                [cx + sx / 2, cy + sy / 2],
                [cx - sx / 2, cy + sy / 2],
            ]
        )
        negatives.append(
            NegativeObstacle(
                obstacle_id=pid, kind="pit", outline_xy_m=outline, depth_m=depth, floor_z_m=rim - depth
            )
        )
    track = Track(centreline_xy_m=np.array([[0.0, 0.0], [0.0, length_m - 10.0]]), width_m=6.0)
    return Terrain(
        heightfield=HeightField(heights_m=h, resolution_m=RES_M, origin_m=origin),
        track=track,
        negative_obstacles=tuple(negatives),
        positive_obstacles=positives,
        start_xy_yaw=(0.0, 0.0, 0.0),
        goal_xy_m=(0.0, length_m - 10.0),
        seed=seed,
    )
