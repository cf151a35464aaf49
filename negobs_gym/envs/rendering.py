"""Top-down frames of an episode, drawn with numpy (no matplotlib per frame).

A frame has two panels side by side, both ``RenderConfig.height_px`` tall:

- **overview** (left): the whole terrain (hillshade, ground-truth obstacles), the vehicle's path
  and footprint, and a caption the caller gives (the envs: time, speed, applied action, the
  filter's d and R(v); Pillow's default font). The terrain image comes from
  :func:`negobs_gym.sim.render.render_top_down` once per terrain and height (cached); path and
  vehicle are drawn on a copy each frame.
- **local** (right): the vehicle-centred observation grid (vehicle driving up the image), with the
  last frame's LiDAR returns (sub-sampled, coloured by height in the vehicle frame), the
  detector's negative-obstacle outlines (yellow), the ground-truth outlines (white), the vehicle
  footprint, and the safety filter's state: a border (green = action passed, red = vetoed, grey =
  no filter decision for this step), the sides of the corridor it searched (grey, along the
  proposed steering's arc) and two marks across that corridor, the hazard distance d (orange) and
  the braking distance R(v) (cyan), each where the filter's arc length puts it, laid out from the
  pose at which the filter decided (the previous step's).

The frame shape depends only on the config and the observation grid's extent, so it is constant
over an episode (``gymnasium.wrappers.RecordVideo`` needs that).
"""

from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from negobs_gym.core.geometry import vehicle_to_world_xy, world_to_vehicle_xy
from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, require
from negobs_gym.safety.corridor import Corridor
from negobs_gym.safety.decision import SafetyDecision
from negobs_gym.sim.render import render_top_down
from negobs_gym.sim.types import Terrain
from negobs_gym.spec.observation import ObservationConfig
from negobs_gym.spec.render import RenderConfig

__all__ = ["RenderConfig", "VehicleFootprint", "caption_lines", "frame_shape", "render_frame", "show_frame"]

Colour = tuple[int, int, int]

UNKNOWN: Colour = (25, 25, 25)
OBSERVED: Colour = (60, 60, 60)
TRAVERSABLE: Colour = (0, 85, 0)
NEGATIVE_CELL: Colour = (150, 0, 0)
POSITIVE_CELL: Colour = (0, 40, 170)
PATH: Colour = (255, 255, 0)
VEHICLE: Colour = (255, 150, 0)
DETECTED_OUTLINE: Colour = (255, 230, 0)
TRUTH_OUTLINE: Colour = (255, 255, 255)
HAZARD_MARK: Colour = (255, 90, 0)
BRAKING_MARK: Colour = (0, 220, 255)
CORRIDOR: Colour = (170, 170, 170)
CAPTION_BOX: Colour = (20, 20, 20)
CAPTION_TEXT: Colour = (255, 255, 255)
BORDER_PASS: Colour = (0, 200, 0)
BORDER_VETO: Colour = (230, 0, 0)
BORDER_NONE: Colour = (110, 110, 110)
# Height ramp of the LiDAR points: low (pit floors) -> ground -> high (obstacles).
POINT_RAMP: tuple[Colour, Colour, Colour] = ((40, 110, 255), (225, 225, 225), (255, 160, 0))


@dataclass(frozen=True, kw_only=True)
class VehicleFootprint:
    """Footprint drawn for the vehicle (pose origin at the rear axle, Y forward) [m]."""

    width_m: float = 2.0
    length_m: float = 4.5
    rear_overhang_m: float = 0.85

    def __post_init__(self) -> None:
        for name in ("width_m", "length_m", "rear_overhang_m"):
            v = getattr(self, name)
            require(math.isfinite(v) and v >= 0, name, f"must be finite and >= 0, got {v!r}")

    def corners_vehicle_m(self) -> np.ndarray:
        """(4, 2) corners in the vehicle frame (x right, y forward)."""
        hw, rear, front = 0.5 * self.width_m, -self.rear_overhang_m, self.length_m - self.rear_overhang_m
        return np.array([[-hw, rear], [hw, rear], [hw, front], [-hw, front]])


def _local_size_px(grid: GridSpec, height_px: int) -> tuple[float, int]:
    """(pixels per metre, even width) of the local panel for ``grid``."""
    ppm = height_px / (grid.ahead_m + grid.back_m)
    width = max(16, 2 * round(grid.side_m * ppm))  # 2 * side_m * ppm, rounded to an even number
    return ppm, width


def frame_shape(obs_config: ObservationConfig, config: RenderConfig | None = None) -> tuple[int, int, int]:
    """(H, W, 3) of every frame :func:`render_frame` draws for this observation config."""
    config = config if config is not None else RenderConfig()
    _, local_w = _local_size_px(obs_config.grid, config.height_px)
    return config.height_px, config.overview_width_px + local_w, 3


# -- cached pieces ---------------------------------------------------------------------------------
_BACKGROUNDS: weakref.WeakKeyDictionary[Terrain, dict[tuple[int, int], np.ndarray]] = (
    weakref.WeakKeyDictionary()
)


def _overview_background(terrain: Terrain, height_px: int, width_px: int) -> np.ndarray:
    """Terrain image (matplotlib, once per terrain and size); read-only, copy before drawing."""
    per_terrain = _BACKGROUNDS.setdefault(terrain, {})
    key = (height_px, width_px)
    if key not in per_terrain:
        image = render_top_down(terrain, height_px=height_px, width_px=width_px)
        image.setflags(write=False)
        per_terrain[key] = image
    return per_terrain[key]


@functools.lru_cache(maxsize=16)
def _grid_lookup(
    grid: GridSpec, downsample: int, height_px: int, width_px: int
) -> tuple[np.ndarray, np.ndarray]:
    """Down-sampled grid (row, col) shown at each local-panel pixel row and column."""
    ppm = height_px / (grid.ahead_m + grid.back_m)
    cell = grid.cell_m * downsample
    y = grid.ahead_m - (np.arange(height_px) + 0.5) / ppm
    x = -grid.side_m + (np.arange(width_px) + 0.5) * (2 * grid.side_m / width_px)
    rows = np.clip(np.floor((y + grid.back_m) / cell).astype(np.int64), 0, grid.rows // downsample - 1)
    cols = np.clip(np.floor((x + grid.side_m) / cell).astype(np.int64), 0, grid.cols // downsample - 1)
    rows.setflags(write=False)
    cols.setflags(write=False)
    return rows, cols


# -- numpy drawing ---------------------------------------------------------------------------------
def _stamp(img: np.ndarray, rows: np.ndarray, cols: np.ndarray, colour: Any, size: int = 1) -> None:
    """Set ``size`` x ``size`` squares at pixel (row, col) to ``colour`` (one or per point), clipped."""
    rows = np.asarray(rows, dtype=np.float64)
    cols = np.asarray(cols, dtype=np.float64)
    ok = np.isfinite(rows) & np.isfinite(cols)
    r0 = np.floor(rows[ok]).astype(np.int64) - (size - 1) // 2
    c0 = np.floor(cols[ok]).astype(np.int64) - (size - 1) // 2
    colour = np.asarray(colour, dtype=np.uint8)
    if colour.ndim == 2:
        colour = colour[ok]
    off = np.arange(size)
    rr = (r0[:, None, None] + off[None, :, None]).repeat(size, axis=2)
    cc = (c0[:, None, None] + off[None, None, :]).repeat(size, axis=1)
    inside = (rr >= 0) & (rr < img.shape[0]) & (cc >= 0) & (cc < img.shape[1])
    if colour.ndim == 2:
        colour = np.broadcast_to(colour[:, None, None, :], (*rr.shape, 3))[inside]
    img[rr[inside], cc[inside]] = colour


def _polyline(
    img: np.ndarray, rows: np.ndarray, cols: np.ndarray, colour: Colour, *, closed: bool, size: int
) -> None:
    """Draw the polyline through pixel vertices (sampled every half pixel), closed if asked."""
    rows = np.asarray(rows, dtype=np.float64)
    cols = np.asarray(cols, dtype=np.float64)
    ok = np.isfinite(rows) & np.isfinite(cols)
    rows, cols = rows[ok], cols[ok]
    if rows.size == 0:
        return
    if closed and rows.size > 1:
        rows, cols = np.append(rows, rows[0]), np.append(cols, cols[0])
    seg = np.hypot(np.diff(rows), np.diff(cols))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    # Bound the samples so a path far outside the image cannot allocate without limit.
    n = int(min(max(2, math.ceil(2.0 * s[-1]) + 1), 8 * (img.shape[0] + img.shape[1]) * max(1, rows.size)))
    t = np.linspace(0.0, s[-1], n)
    _stamp(img, np.interp(t, s, rows), np.interp(t, s, cols), colour, size)


def _height_colours(z_m: np.ndarray, z_range_m: tuple[float, float]) -> np.ndarray:
    """(N, 3) uint8 colours of the three-stop height ramp."""
    lo, hi = z_range_m
    t = np.clip((z_m - lo) / (hi - lo), 0.0, 1.0) * 2.0  # 0..1 first half, 1..2 second half
    ramp = np.asarray(POINT_RAMP, dtype=np.float64)
    k = np.minimum(t.astype(np.int64), 1)
    f = (t - k)[:, None]
    return (ramp[k] * (1.0 - f) + ramp[k + 1] * f).astype(np.uint8)


# -- panels ----------------------------------------------------------------------------------------
def _overview(
    terrain: Terrain, pose: Pose, path_xy_m: np.ndarray, footprint: VehicleFootprint, config: RenderConfig
) -> np.ndarray:
    h, w = config.height_px, config.overview_width_px
    img = _overview_background(terrain, h, w).copy()
    hf = terrain.heightfield
    x0, x1, y0, y1 = hf.extent_m
    half = 0.5 * hf.resolution_m
    # render_top_down's axes span the terrain extent plus half a sample on each side.
    sx, sy = w / (x1 - x0 + 2 * half), h / (y1 - y0 + 2 * half)

    def to_px(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (y1 + half - xy[:, 1]) * sy, (xy[:, 0] - (x0 - half)) * sx

    path = np.asarray(path_xy_m, dtype=np.float64).reshape(-1, 2)
    if len(path) > 0:
        _polyline(img, *to_px(path), PATH, closed=False, size=2)
    corners = vehicle_to_world_xy(footprint.corners_vehicle_m(), (pose.x, pose.y), pose.yaw)
    _polyline(img, *to_px(corners), VEHICLE, closed=True, size=2)
    return img


def _grid_image(
    grid: np.ndarray | None, obs_config: ObservationConfig, height_px: int, width_px: int
) -> np.ndarray:
    """Local-panel background: the observed grid's channels as colours (unknown where none)."""
    img = np.empty((height_px, width_px, 3), np.uint8)
    img[:] = UNKNOWN
    if grid is None:
        return img
    expected = obs_config.shape
    if grid.shape != expected:
        raise ConfigError("grid", f"must have the observation shape {expected}, got {grid.shape}")
    rows, cols = _grid_lookup(obs_config.grid, obs_config.downsample, height_px, width_px)
    cells = np.empty((*grid.shape[1:], 3), np.uint8)
    cells[:] = UNKNOWN
    layer = {name: grid[k] > 0 for k, name in enumerate(obs_config.channels)}
    for name, colour in (
        ("observed", OBSERVED),
        ("traversable", TRAVERSABLE),
        ("positive", POSITIVE_CELL),
        ("negative", NEGATIVE_CELL),
    ):
        if name in layer:
            cells[layer[name]] = colour
    return cells[rows[:, None], cols[None, :]]


def _local(
    terrain: Terrain,
    pose: Pose,
    grid: np.ndarray | None,
    obs_config: ObservationConfig,
    points_vehicle_m: np.ndarray | None,
    detected_outlines_m: Sequence[np.ndarray],
    safety: SafetyDecision | None,
    decision_pose: Pose | None,
    footprint: VehicleFootprint,
    config: RenderConfig,
) -> np.ndarray:
    spec = obs_config.grid
    ppm, w = _local_size_px(spec, config.height_px)
    h = config.height_px
    img = _grid_image(grid, obs_config, h, w)
    ppm_x = w / (2 * spec.side_m)

    def to_px(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return (spec.ahead_m - xy[:, 1]) * ppm, (xy[:, 0] + spec.side_m) * ppm_x

    if points_vehicle_m is not None:
        pts = np.asarray(points_vehicle_m, dtype=np.float64).reshape(-1, 3)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts) > config.max_points:
            pts = pts[np.linspace(0, len(pts) - 1, config.max_points).astype(np.int64)]
        if len(pts):
            _stamp(img, *to_px(pts[:, :2]), _height_colours(pts[:, 2], config.point_z_range_m), 1)
    for ob in terrain.negative_obstacles:
        outline = world_to_vehicle_xy(ob.outline_xy_m, (pose.x, pose.y), pose.yaw)
        _polyline(img, *to_px(outline), TRUTH_OUTLINE, closed=True, size=1)
    for outline in detected_outlines_m:
        _polyline(img, *to_px(outline), DETECTED_OUTLINE, closed=True, size=2)
    _polyline(img, *to_px(footprint.corners_vehicle_m()), VEHICLE, closed=True, size=2)
    reach_m = math.hypot(spec.ahead_m, spec.side_m)  # any arc this long leaves the panel
    if decision_pose is None:
        decision_px = to_px
    else:  # the corridor lies where it was when the filter decided: into the current frame

        def decision_px(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            world = vehicle_to_world_xy(xy, (decision_pose.x, decision_pose.y), decision_pose.yaw)
            return to_px(world_to_vehicle_xy(world, (pose.x, pose.y), pose.yaw))

    _draw_safety(img, safety, footprint, reach_m, decision_px, config)
    return img


def caption_lines(
    time_s: float, speed_mps: float, action: np.ndarray | None, safety: SafetyDecision | None
) -> list[str]:
    """The envs' frame caption: episode time and speed, the action the last step applied (None
    before the first step), and the safety filter's d, R(v) and veto when it decided that step."""
    speed_kmh = round(3.6 * speed_mps, 1) + 0.0  # + 0.0: a standstill's -0.0 reads 0.0
    lines = [f"t {time_s:5.1f} s  {speed_kmh:5.1f} km/h"]
    if action is not None:
        lines.append(f"throttle {action[0]:+.2f} steer {action[1]:+.2f}")
    if safety is not None:
        d_m = safety.hazard_distance_m
        d = f"{d_m:.1f} m" if math.isfinite(d_m) else "clear"
        lines.append(f"d {d}  R {safety.braking_distance_m:.1f} m" + ("  VETO" if safety.vetoed else ""))
    return lines


@functools.cache
def _caption_font() -> Any:
    from PIL import ImageFont

    return ImageFont.load_default()


def _write_caption(img: np.ndarray, lines: Sequence[str]) -> None:
    """White ``lines`` on a dark box at the top left of ``img`` (Pillow's own font: matplotlib,
    which every install has, depends on Pillow)."""
    from PIL import Image, ImageDraw

    text = "\n".join(lines)
    canvas = Image.fromarray(img)
    draw = ImageDraw.Draw(canvas)
    _, _, right, bottom = draw.multiline_textbbox((4, 3), text, font=_caption_font(), spacing=2)
    draw.rectangle((0, 0, right + 3, bottom + 3), fill=CAPTION_BOX)
    draw.multiline_text((4, 3), text, fill=CAPTION_TEXT, font=_caption_font(), spacing=2)
    img[:] = np.asarray(canvas)


def _draw_safety(
    img: np.ndarray,
    safety: SafetyDecision | None,
    footprint: VehicleFootprint,
    reach_m: float,
    to_px: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    config: RenderConfig,
) -> None:
    """Border by the filter's decision; the corridor it searched and the d / R(v) marks across it."""
    b = config.border_px
    if safety is None:
        colour = BORDER_NONE
    else:
        colour = BORDER_VETO if safety.vetoed else BORDER_PASS
        corridor = safety.corridor
        if corridor is None:  # a decision made without one: straight ahead, a little wider than the car
            corridor = Corridor(steer_rad=0.0, wheelbase_m=1.0, half_width_m=0.5 * footprint.width_m + 0.5)
        for side in corridor.sides_xy_m(reach_m):
            _polyline(img, *to_px(side), CORRIDOR, closed=False, size=1)
        for d, mark in ((safety.hazard_distance_m, HAZARD_MARK), (safety.braking_distance_m, BRAKING_MARK)):
            if math.isfinite(d) and d >= 0:
                _polyline(
                    img,
                    *to_px(corridor.reached_at_xy_m(d)),
                    mark,
                    closed=False,
                    size=config.mark_thickness_px,
                )
    img[:b] = colour
    img[-b:] = colour
    img[:, :b] = colour
    img[:, -b:] = colour


def render_frame(
    terrain: Terrain,
    pose: Pose,
    path_xy_m: np.ndarray,
    grid: np.ndarray | None,
    obs_config: ObservationConfig,
    *,
    points_vehicle_m: np.ndarray | None = None,
    detected_outlines_m: Sequence[np.ndarray] = (),
    safety: SafetyDecision | None = None,
    decision_pose: Pose | None = None,
    footprint: VehicleFootprint | None = None,
    config: RenderConfig | None = None,
    caption: Sequence[str] = (),
) -> np.ndarray:
    """(H, W, 3) uint8 frame: whole-terrain overview on the left, vehicle-centred view on the right.

    Args:
        terrain: the episode's terrain (its background image is cached per terrain).
        pose: the vehicle's true pose.
        path_xy_m: (N, 2) world positions driven so far.
        grid: the last ``grid`` observation (channels, rows, cols) or None (nothing observed yet).
        obs_config: the env's observation config (channels, grid extent, down-sampling).
        points_vehicle_m: (N, 3) vehicle-frame LiDAR returns of the last frame; non-finite rows
            are skipped, more than ``config.max_points`` are evenly strided.
        detected_outlines_m: vehicle-frame (k, 2) outlines of the detected negative obstacles.
        safety: the safety filter's decision for this step (border by ``vetoed``, its
            ``corridor`` drawn, marks across it at ``hazard_distance_m`` and
            ``braking_distance_m``; straight ahead when it has no corridor) or None when no
            filter decided.
        decision_pose: the true pose at which the filter decided (the step before ``pose``): the
            corridor and marks, in that pose's vehicle frame, are drawn where they lie in the
            current one; None draws them in the current frame.
        footprint: vehicle outline; default 2.0 x 4.5 m with 0.85 m rear overhang.
        config: layout, see :class:`RenderConfig`.
        caption: lines of text for the top left of the overview (drawn when ``config.caption``).

    Raises:
        ValueError: ``grid`` does not have the observation shape of ``obs_config``.
    """
    config = config if config is not None else RenderConfig()
    footprint = footprint if footprint is not None else VehicleFootprint()
    overview = _overview(terrain, pose, path_xy_m, footprint, config)
    if config.caption and caption:
        _write_caption(overview, caption)
    local = _local(
        terrain,
        pose,
        grid,
        obs_config,
        points_vehicle_m,
        detected_outlines_m,
        safety,
        decision_pose,
        footprint,
        config,
    )
    return np.concatenate([overview, local], axis=1)


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
