"""The top-down render writes a PNG of the asked size with red where a pit is."""

from __future__ import annotations

import os

import matplotlib.image as mpimg
import numpy as np
import pytest

from negobs_gym.core import Pose
from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.sim import presets
from negobs_gym.sim.render import render_drive, render_top_down


def _pixel(terrain, xy, shape):
    x0, x1, y0, y1 = terrain.heightfield.extent_m
    half = 0.5 * terrain.heightfield.resolution_m
    x0, x1, y0, y1 = x0 - half, x1 + half, y0 - half, y1 + half
    h, w = shape[:2]
    col = int((xy[0] - x0) / (x1 - x0) * w)
    row = int((y1 - xy[1]) / (y1 - y0) * h)
    return row, col


def _is_red(rgb) -> bool:
    r, g, b = (int(v) for v in rgb)
    return r > 180 and g < 90 and b < 90


def test_png_written_with_size_and_red_pit(tmp_path) -> None:
    terrain = presets.braking_track(
        ditch_distance_m=12.0,
        ditch_length_m=2.0,
        ditch_width_m=3.0,
        lateral_offset_m=-2.0,
        seed=0,
        resolution_m=0.2,
    )
    out = tmp_path / "sub" / "top.png"
    path = np.stack([np.zeros(20), np.linspace(0.0, 8.0, 20)], axis=1)
    pose = Pose(x=0.0, y=8.0, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)
    image = render_top_down(
        terrain, path_xy_m=path, vehicle_pose=pose, out_path=out, height_px=400, width_px=200
    )
    assert image.shape == (400, 200, 3) and image.dtype == np.uint8
    assert list(out.parent.iterdir()) == [out]  # no temp file left behind
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask  # usual permissions, not mkstemp's 0600
    on_disk = mpimg.imread(out)
    assert on_disk.shape[:2] == (400, 200)
    row, col = _pixel(terrain, terrain.negative_obstacles[0].centre_xy_m, image.shape)
    assert _is_red(image[row, col])
    # Far from the ditch there is no red.
    row, col = _pixel(terrain, (8.0, 30.0), image.shape)
    assert not _is_red(image[row, col])


def test_default_width_follows_terrain_aspect() -> None:
    terrain = presets.rough_track(length_m=40.0, seed=0, resolution_m=0.2)
    image = render_top_down(terrain, height_px=300)
    x0, x1, y0, y1 = terrain.heightfield.extent_m
    assert image.shape[1] == pytest.approx(300 * (x1 - x0) / (y1 - y0), abs=1)


def test_a_view_draws_that_window_only() -> None:
    """A view of the pit's surroundings: the pit fills the middle, the image is square."""
    terrain = presets.braking_track(
        ditch_distance_m=12.0,
        ditch_length_m=2.0,
        ditch_width_m=2.0,
        lateral_offset_m=0.0,
        seed=0,
        resolution_m=0.2,
    )
    cx, cy = terrain.negative_obstacles[0].centre_xy_m
    image = render_top_down(terrain, height_px=200, view_m=(cx - 4.0, cx + 4.0, cy - 4.0, cy + 4.0))
    assert image.shape == (200, 200, 3)
    assert _is_red(image[100, 100])  # the pit's middle is the picture's
    assert not _is_red(image[5, 5])  # 4 m off, beyond the 2 m pit
    for bad in ((0.0, 0.0, 0.0, 1.0), (0.0, 1.0, float("nan"), 2.0)):
        with pytest.raises(ConfigError, match="view_m"):
            render_top_down(terrain, height_px=100, view_m=bad)


def test_bad_path_raises() -> None:
    terrain = presets.rough_track(length_m=20.0, seed=0, resolution_m=0.2)
    with pytest.raises(GeometryError, match="path_xy_m"):
        render_top_down(terrain, path_xy_m=np.zeros((5, 3)), height_px=100)


def test_marks_and_caption_are_drawn() -> None:
    terrain = presets.rough_track(length_m=40.0, seed=0, resolution_m=0.2)
    plain = render_top_down(terrain, height_px=400)
    mark = np.array([[0.0, 20.0]])
    marked = render_top_down(terrain, height_px=400, marks_xy_m=mark, caption="seed 0: goal")
    row, col = _pixel(terrain, mark[0], marked.shape)
    r, g, b = (int(v) for v in marked[row, col])
    assert r > 200 and g < 80 and b > 200  # magenta
    assert not np.array_equal(plain[:20, :60], marked[:20, :60])  # the caption's box, top left
    assert np.array_equal(plain[-50:], marked[-50:])  # nothing else changed far from both


def test_missed_vetoes_are_drawn_as_crosses_of_their_own_colour() -> None:
    terrain = presets.rough_track(length_m=40.0, seed=0, resolution_m=0.2)
    path = np.array([[0.0, 5.0], [0.0, 12.0], [0.0, 20.0], [0.0, 28.0]])
    vetoed, missed = np.array([0, 1, 0, 0], bool), np.array([0, 0, 1, 0], bool)
    image = render_drive(terrain, path, 0.0, vetoed, "", None, None, missed)
    row, col = _pixel(terrain, path[2], image.shape)
    r, g, b = (int(v) for v in image[row, col])
    assert r < 80 and g > 200 and b > 200  # cyan, at the missed step's point
    without = render_drive(terrain, path, 0.0, vetoed, "", None, None)
    changed = np.flatnonzero(np.any(image != without, axis=(1, 2)))
    assert changed.size and abs(changed.min() - row) <= 10 and abs(changed.max() - row) <= 10  # only there
