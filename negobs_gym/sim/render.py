"""Top-down render of a terrain: hillshade, ground-truth obstacles, the vehicle's path.

Uses matplotlib's Agg canvas (no display needed). The axes fill the whole figure with the terrain
extent as limits, so pixel (row, col) maps linearly to world (x, y): ``col = (x - x_min) / (x_max -
x_min) * width``, ``row = (y_max - y) / (y_max - y_min) * height``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from negobs_gym.core import Pose
from negobs_gym.core.files import write_atomic
from negobs_gym.core.geometry import heading_axes, vehicle_to_world_xy
from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.sim.types import Terrain

if TYPE_CHECKING:
    from matplotlib.axes import Axes

NEGATIVE_COLOUR = "red"
POSITIVE_COLOUR = "blue"
PATH_COLOUR = "yellow"
VEHICLE_COLOUR = "orange"
MARK_COLOUR = "magenta"
MISSED_COLOUR = "cyan"
TRACK_EDGE_COLOUR = "white"


def _patches():
    from matplotlib import patches

    return patches


def draw_terrain(
    ax: Axes,
    terrain: Terrain,
    *,
    vertical_exaggeration: float = 3.0,
    show_track_edges: bool = True,
) -> None:
    """Draw the hillshaded heightfield and the ground-truth obstacles onto ``ax`` (world metres).

    Negative obstacles are filled and outlined in red, positive ones outlined in blue. Other
    layers (LiDAR points, grid cells) can be drawn on the same axes afterwards.
    """
    from matplotlib.colors import LightSource

    patches = _patches()
    hf = terrain.heightfield
    x0, x1, y0, y1 = hf.extent_m
    heights = np.asarray(hf.heights_m, dtype=np.float64)
    light = LightSource(azdeg=315, altdeg=45)
    shade = light.hillshade(heights, vert_exag=vertical_exaggeration, dx=hf.resolution_m, dy=hf.resolution_m)
    # Row 0 of the heightfield is the lowest y: draw with origin="lower".
    half = 0.5 * hf.resolution_m
    ax.imshow(
        shade,
        cmap="gray",
        vmin=0.0,
        vmax=1.0,
        origin="lower",
        extent=(x0 - half, x1 + half, y0 - half, y1 + half),
        interpolation="bilinear",
        aspect="auto",
    )
    if show_track_edges:
        track = terrain.track
        s = np.linspace(0.0, track.length_m, max(len(track.centreline_xy_m), 2))
        for side in (-0.5, 0.5):
            edge, _ = track.pose_at(s, side * track.width_m)
            ax.plot(edge[:, 0], edge[:, 1], color=TRACK_EDGE_COLOUR, lw=0.6, alpha=0.6)
    for neg in terrain.negative_obstacles:
        ax.add_patch(
            patches.Polygon(
                np.asarray(neg.outline_xy_m),
                closed=True,
                facecolor=NEGATIVE_COLOUR,
                edgecolor=NEGATIVE_COLOUR,
                alpha=0.8,
                lw=1.5,
            )
        )
    for pos in terrain.positive_obstacles:
        ax.add_patch(_footprint(pos.shape, pos.centre_m[:2], pos.half_extents_m, pos.yaw_rad))
    ax.set_xlim(x0 - half, x1 + half)
    ax.set_ylim(y0 - half, y1 + half)


def _footprint(shape: str, centre_xy: np.ndarray, half_extents: np.ndarray, yaw_rad: float):
    patches = _patches()
    if shape == "cylinder":
        return patches.Circle(
            tuple(centre_xy), float(half_extents[0]), fill=False, edgecolor=POSITIVE_COLOUR, lw=1.5
        )
    return patches.Polygon(
        _box_corners(centre_xy, half_extents[0], half_extents[1], yaw_rad),
        closed=True,
        fill=False,
        edgecolor=POSITIVE_COLOUR,
        lw=1.5,
    )


def _box_corners(centre_xy: np.ndarray, half_x: float, half_y: float, yaw_rad: float) -> np.ndarray:
    """Corners of a box with body X right, Y forward, yawed by ``yaw_rad`` (core/pose.py)."""
    local = np.array([[-half_x, -half_y], [half_x, -half_y], [half_x, half_y], [-half_x, half_y]])
    return vehicle_to_world_xy(local, centre_xy, yaw_rad)


def render_top_down(
    terrain: Terrain,
    path_xy_m: np.ndarray | None = None,
    vehicle_pose: Pose | None = None,
    out_path: str | os.PathLike | None = None,
    *,
    height_px: int = 1000,
    width_px: int | None = None,
    vehicle_size_m: tuple[float, float] = (2.0, 4.5),
    rear_overhang_m: float = 0.85,
    marks_xy_m: np.ndarray | None = None,
    missed_xy_m: np.ndarray | None = None,
    caption: str | None = None,
    view_m: tuple[float, float, float, float] | None = None,
) -> np.ndarray:
    """Render the terrain from above; returns an (H, W, 3) uint8 image, writes a PNG if asked.

    Args:
        terrain: the terrain to draw.
        path_xy_m: (N, 2) world path of the vehicle, drawn as a line.
        vehicle_pose: the vehicle's pose (origin at the rear axle, yaw 0 facing +Y); its
            footprint of ``vehicle_size_m`` is drawn.
        out_path: PNG file to write atomically (temp file + ``os.replace``).
        height_px: image height; ``width_px`` defaults to the view's aspect ratio (>= 64 px).
        vehicle_size_m: (width, length) of the footprint [m].
        rear_overhang_m: distance from the rear axle (pose origin) back to the rear bumper [m].
        marks_xy_m: (M, 2) world points drawn as dots (e.g. where the safety filter vetoed).
        missed_xy_m: (K, 2) world points drawn as crosses (where the filter let the car on with a
            true hazard well inside its braking distance: missed vetoes).
        caption: one line of text drawn at the top left.
        view_m: the world window ``(x0, x1, y0, y1)`` to draw [m]; None: the whole terrain.

    Raises:
        ConfigError: an image under 16 px or an empty or non-finite view.
        GeometryError: a malformed path.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    x0, x1, y0, y1 = terrain.heightfield.extent_m if view_m is None else view_m
    if not (np.all(np.isfinite([x0, x1, y0, y1])) and x1 > x0 and y1 > y0):
        raise ConfigError("view_m", f"must be a finite window (x0 < x1, y0 < y1), got {view_m!r}")
    if width_px is None:
        width_px = max(64, round(height_px * (x1 - x0) / max(y1 - y0, 1e-9)))
    if height_px < 16 or width_px < 16:
        raise ConfigError("width_px/height_px", f"must be at least 16x16 px, got {width_px}x{height_px}")
    dpi = 100
    fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_axis_off()
    draw_terrain(ax, terrain)
    if view_m is not None:
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
    if path_xy_m is not None:
        path = np.asarray(path_xy_m, dtype=np.float64)
        if path.ndim != 2 or path.shape[1] != 2:
            raise GeometryError(f"path_xy_m must have shape (N, 2), got {path.shape}")
        finite = np.all(np.isfinite(path), axis=1)
        ax.plot(path[finite, 0], path[finite, 1], color=PATH_COLOUR, lw=1.5)
    if marks_xy_m is not None:
        marks = np.asarray(marks_xy_m, dtype=np.float64).reshape(-1, 2)
        ax.plot(marks[:, 0], marks[:, 1], ".", color=MARK_COLOUR, ms=4)
    if missed_xy_m is not None:
        missed = np.asarray(missed_xy_m, dtype=np.float64).reshape(-1, 2)
        ax.plot(missed[:, 0], missed[:, 1], "x", color=MISSED_COLOUR, ms=6, mew=1.5)
    if vehicle_pose is not None:
        width, length = vehicle_size_m
        x, y, yaw = float(vehicle_pose.x), float(vehicle_pose.y), float(vehicle_pose.yaw)
        fwd, _ = heading_axes(yaw)
        # The pose origin is the rear axle: the footprint centre lies length/2 - overhang ahead.
        centre = np.array([x, y]) + fwd * (0.5 * length - rear_overhang_m)
        corners = _box_corners(centre, 0.5 * width, 0.5 * length, yaw)
        ax.add_patch(_patches().Polygon(corners, closed=True, fill=False, edgecolor=VEHICLE_COLOUR, lw=2))
    if caption:
        ax.text(
            0.01,
            0.99,
            caption,
            transform=ax.transAxes,
            va="top",
            ha="left",
            fontsize=9,
            color="white",
            bbox={"facecolor": "black", "alpha": 0.6, "edgecolor": "none"},
        )
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    if out_path is not None:
        write_png_atomic(image, Path(out_path))
    return image


def render_drive(
    terrain: Terrain,
    path_xy_m: np.ndarray,
    end_yaw_rad: float,
    vetoed: np.ndarray,
    caption: str,
    out_path: str | os.PathLike,
    zoom_m: float | None = None,
    missed: np.ndarray | None = None,
) -> np.ndarray:
    """One drive from above (``negobs eval paths``, ``negobs scenario run --draw``): the path, the
    car where it ended (at the path's last point, heading ``end_yaw_rad``), the path's points where
    ``vetoed`` (a bool per point) as marks, those where ``missed`` (a bool per point: missed
    vetoes, :mod:`negobs_gym.eval.vetoes`) as crosses, and ``caption``; written to ``out_path``. ``zoom_m``:
    only the square of that half-width around where the car ended (1000 px a side), to see how it
    ended; None: the whole terrain."""
    path = np.asarray(path_xy_m, dtype=np.float64).reshape(-1, 2)
    end = Pose(x=path[-1, 0], y=path[-1, 1], yaw=end_yaw_rad)
    marks = path[np.asarray(vetoed, dtype=bool)]
    view = None
    if zoom_m is not None:
        if not (np.isfinite(zoom_m) and zoom_m > 0):
            raise ConfigError("zoom_m", f"must be finite and > 0, got {zoom_m!r}")
        view = (end.x - zoom_m, end.x + zoom_m, end.y - zoom_m, end.y + zoom_m)
    crosses = None if missed is None else path[np.asarray(missed, dtype=bool)]
    return render_top_down(
        terrain, path, end, out_path, marks_xy_m=marks, missed_xy_m=crosses, caption=caption, view_m=view
    )


def write_png_atomic(image: np.ndarray, out_path: Path) -> None:
    """Write ``image`` as PNG atomically (:func:`negobs_gym.core.files.write_atomic`)."""
    import matplotlib.image as mpimg

    write_atomic(out_path, lambda tmp: mpimg.imsave(tmp, image, format="png"))
