"""Top-down frames of an episode: terrain, ground-truth outlines, path, vehicle, observed grid."""

from __future__ import annotations

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.envs.config import ObservationConfig
from negobs_gym.sim.render import render_top_down
from negobs_gym.sim.types import Terrain

__all__ = ["render_frame", "show_frame"]

GRID_TINT = {"negative": (255, 0, 0), "positive": (0, 0, 255)}


def render_frame(
    terrain: Terrain,
    pose: Pose,
    path_xy_m: np.ndarray,
    grid: np.ndarray | None,
    obs_config: ObservationConfig,
    *,
    height_px: int = 480,
) -> np.ndarray:
    """(H, W, 3) uint8 frame: the terrain render with an inset of the observed grid on the right."""
    frame = render_top_down(
        terrain, path_xy_m=path_xy_m, vehicle_pose=pose, height_px=height_px, width_px=160
    )
    if grid is None:
        return frame
    _, rows, cols = grid.shape
    inset = np.full((rows, cols, 3), 40, np.uint8)
    for k, name in enumerate(obs_config.channels):
        if name == "traversable":
            inset[grid[k] > 0] = (0, 160, 0)
    for k, name in enumerate(obs_config.channels):
        if name in GRID_TINT:
            inset[grid[k] > 0] = GRID_TINT[name]
    scale = max(1, height_px // rows)
    inset = np.repeat(np.repeat(inset[::-1], scale, axis=0), scale, axis=1)[:height_px]
    pad = np.zeros((height_px, inset.shape[1], 3), np.uint8)
    pad[: inset.shape[0]] = inset
    return np.concatenate([frame, pad], axis=1)


def show_frame(frame: np.ndarray, handle):
    """Show ``frame`` in a matplotlib window, reusing ``handle`` = (figure, image) when given."""
    import matplotlib.pyplot as plt

    if handle is None:
        fig, ax = plt.subplots()
        ax.set_axis_off()
        handle = (fig, ax.imshow(frame))
    else:
        handle[1].set_data(frame)
    plt.pause(0.001)
    return handle
