"""Unit tests of the detection-recall evaluation on hand-made outlines."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.eval import (
    DetectionEvalConfig,
    RecallTable,
    components_from_grid,
    match_frame,
    rasterize_outline,
    track_border_mask,
    world_outline_to_vehicle,
)

GRID = GridSpec()


def square(cx: float, cy: float, side: float) -> np.ndarray:
    h = side / 2
    return np.array([[cx - h, cy - h], [cx + h, cy - h], [cx + h, cy + h], [cx - h, cy + h]])


def test_rasterize_one_metre_square_is_25_cells() -> None:
    # 1 m square aligned to the 20 cm grid: exactly 5 x 5 cell centres inside
    mask = rasterize_outline(square(0.5, 8.5, 1.0), GRID)
    assert mask.sum() == 25
    rows, cols = np.nonzero(mask)
    row, col, _ = GRID.cell_of(np.array([0.5, 8.5]))
    assert rows.min() == row - 2 and rows.max() == row + 2
    assert cols.min() == col - 2 and cols.max() == col + 2


def test_rasterize_triangle_counts_half_of_square() -> None:
    tri = np.array([[0.0, 8.0], [2.0, 8.0], [0.0, 10.0]])
    # 10 x 10 cells under the square, centres strictly below the diagonal: 45
    assert rasterize_outline(tri, GRID).sum() == 45


def test_rasterize_tiny_outline_marks_its_cell() -> None:
    mask = rasterize_outline(np.array([[0.31, 5.05], [0.33, 5.07]]), GRID)
    assert mask.sum() == 1


def test_rasterize_outside_grid_is_empty() -> None:
    assert rasterize_outline(square(0.0, 100.0, 1.0), GRID).sum() == 0


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.array([[0.0, np.nan], [1, 1], [1, 0]]), "NaN"),
        (np.zeros((3,)), "shape"),
        (np.zeros((0, 2)), "shape"),
    ],
)
def test_rasterize_rejects_bad_outline(bad: np.ndarray, match: str) -> None:
    with pytest.raises(GeometryError, match=match):
        rasterize_outline(bad, GRID)


def test_world_outline_to_vehicle_rotates_with_yaw() -> None:
    # yaw = +90 deg: vehicle +Y faces world -X, vehicle +X faces world +Y
    pose = Pose(x=10.0, y=5.0, z=1.0, roll=0.0, pitch=0.0, yaw=math.pi / 2)
    world = np.array([[0.0, 5.0], [10.0, 7.0]])
    veh = world_outline_to_vehicle(world, pose)
    np.testing.assert_allclose(veh, [[0.0, 10.0], [2.0, 0.0]], atol=1e-12)


def test_world_outline_to_vehicle_uses_ground_height_when_pitched() -> None:
    # nose up by 0.1 rad, origin 1 m above the ground: a ground point straight ahead at world y = 10
    # sits below the tilted +Y axis, so its vehicle-frame y is y cos(p) - dz sin(p)
    pitch = 0.1
    pose = Pose(x=0.0, y=0.0, z=1.0, roll=0.0, pitch=pitch, yaw=0.0)
    veh = world_outline_to_vehicle(np.array([[0.0, 10.0]]), pose, ground_z_m=0.0)
    assert veh[0, 1] == pytest.approx(10.0 * math.cos(pitch) - 1.0 * math.sin(pitch))
    with pytest.raises(GeometryError, match="ground_z_m"):
        world_outline_to_vehicle(np.array([[0.0, 10.0]]), pose, ground_z_m=np.nan)


def test_match_recall_and_false_alarm() -> None:
    truth = [square(0.5, 8.5, 1.0), square(-3.0, 12.0, 1.0)]
    detected = [
        square(0.7, 8.3, 0.6),  # overlaps the first truth
        square(5.0, 15.0, 0.6),  # overlaps nothing: a false alarm
    ]
    m = match_frame(detected, truth, GRID)
    np.testing.assert_array_equal(m.truth_recalled, [True, False])
    assert m.false_alarms == 1 and m.detections == 2
    np.testing.assert_array_equal(m.truth_cells, [25, 25])
    # nearest cell centre of the 8-9 m square: (0.1, 8.1); its cells' centre: (0.5, 8.5)
    assert m.truth_distance_m[0] == pytest.approx(math.hypot(0.1, 8.1))
    assert m.truth_centre_distance_m[0] == pytest.approx(math.hypot(0.5, 8.5))


def test_recall_table_bins_by_the_centre_like_paper_n_or_by_the_nearest_cell() -> None:
    pit = square(0.0, 10.5, 1.0)  # cells from 10.1 m to 10.9 m ahead; centre 10.5 m
    edges = (9.0, 10.4, 12.0)
    by_centre = RecallTable(DetectionEvalConfig(distance_bin_edges_m=edges))
    by_nearest = RecallTable(DetectionEvalConfig(distance_bin_edges_m=edges, bin_distance="nearest"))
    for table in (by_centre, by_nearest):
        table.add(match_frame([pit], [pit], GRID))
    assert by_centre.seen[:, 1].sum() == 1 and by_nearest.seen[:, 0].sum() == 1
    with pytest.raises(ConfigError, match="bin_distance"):
        DetectionEvalConfig(bin_distance="rim")


def test_touching_but_not_overlapping_is_not_recalled() -> None:
    truth = [square(0.5, 8.5, 1.0)]  # cells x in [0, 1)
    detected = [square(1.5, 8.5, 1.0)]  # cells x in [1, 2)
    m = match_frame(detected, truth, GRID)
    assert not m.truth_recalled[0] and m.false_alarms == 1


def test_min_overlap_cells_is_respected() -> None:
    truth = [square(0.5, 8.5, 1.0)]
    detected = [np.array([[0.9, 8.9], [0.91, 8.91]])]  # one shared cell
    assert match_frame(detected, truth, GRID).truth_recalled[0]
    strict = DetectionEvalConfig(min_overlap_cells=2)
    assert not match_frame(detected, truth, GRID, strict).truth_recalled[0]


def test_grid_masks_and_components() -> None:
    grid = np.zeros(GRID.shape, dtype=bool)
    grid |= rasterize_outline(square(0.5, 8.5, 1.0), GRID)
    grid |= rasterize_outline(square(6.0, 18.0, 0.6), GRID)
    blobs = components_from_grid(grid)
    assert len(blobs) == 2
    m = match_frame(blobs, [square(0.5, 8.5, 1.0)], GRID)
    assert m.truth_recalled[0] and m.false_alarms == 1
    with pytest.raises(GeometryError, match="mask shape"):
        match_frame([np.zeros((3, 3), dtype=bool)], [], GRID)
    with pytest.raises(GeometryError, match="2-D"):
        components_from_grid(np.zeros(5, dtype=bool))


def test_border_detections_are_not_false_alarms() -> None:
    centre = np.array([[0.0, -5.0], [0.0, 30.0]])
    border = track_border_mask(centre, 8.0, GRID, 0.6)
    # right border at x = 4: cells with centre |x - 4| <= 0.6
    xs = GRID.cell_centres()[0, :, 0]
    np.testing.assert_array_equal(border[0], (np.abs(np.abs(xs) - 4.0) <= 0.6))
    on_border = [square(4.0, 10.0, 0.6)]
    assert match_frame(on_border, [], GRID).false_alarms == 1
    assert match_frame(on_border, [], GRID, border_mask=border).false_alarms == 0
    with pytest.raises(GeometryError, match="border_mask"):
        match_frame(on_border, [], GRID, border_mask=np.zeros((2, 2), dtype=bool))


def test_detection_outside_grid_is_not_judged() -> None:
    m = match_frame([square(0.0, 100.0, 1.0), square(5.0, 15.0, 0.6)], [], GRID)
    assert m.detections == 1 and m.false_alarms == 1


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(-9.0, 9.0), st.floats(-4.0, 29.0), st.floats(0.05, 3.0), st.floats(0.05, 3.0)),
        max_size=6,
    )
)
def test_truth_matched_against_itself(rects: list[tuple[float, float, float, float]]) -> None:
    # a perfect detector recalls every ground truth that has a cell and raises no false alarm
    outlines = [np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]]) for x, y, w, h in rects]
    m = match_frame(outlines, outlines, GRID)
    np.testing.assert_array_equal(m.truth_recalled, m.truth_cells > 0)
    assert m.false_alarms == 0
    assert m.detections == int(np.count_nonzero(m.truth_cells))


def test_empty_frame() -> None:
    m = match_frame([], [], GRID)
    assert m.false_alarms == 0 and m.truth_recalled.shape == (0,)
    m = match_frame([], [square(0.5, 8.5, 1.0)], GRID)
    np.testing.assert_array_equal(m.truth_recalled, [False])


def test_recall_table_bins_like_table_7() -> None:
    table = RecallTable()
    assert table.recall().shape == (7, 7)
    assert math.isnan(table.false_alarms_per_frame())
    near, far = square(0.5, 7.5, 1.0), square(0.5, 13.5, 1.0)  # 25 cells; ~7 m and ~13 m
    table.add(match_frame([near], [near, far], GRID))
    table.add(match_frame([near, far], [near, far], GRID))
    table.add(match_frame([square(8.0, 20.0, 0.4)], [near], GRID))
    rec = table.recall()
    assert rec[2, 0] == pytest.approx(2 / 3)  # 25-29 cells, 6-8 m: recalled in 2 of 3 frames
    assert rec[2, 3] == pytest.approx(0.5)  # 25-29 cells, 12-14 m: 1 of 2
    assert np.isnan(rec[0, 0])
    assert table.seen.sum() == 5
    assert table.false_alarms_per_frame() == pytest.approx(1 / 3)


def test_recall_table_ignores_out_of_bin_truth() -> None:
    table = RecallTable()
    small = square(0.1, 8.1, 0.2)  # 1-4 cells: below the smallest size bin
    table.add(match_frame([small], [small, square(0.5, 25.5, 1.0)], GRID))
    assert table.seen.sum() == 0 and table.frames == 1


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"size_bin_edges_cells": (15,)}, "size_bin_edges_cells"),
        ({"distance_bin_edges_m": (6.0, 6.0)}, "distance_bin_edges_m"),
        ({"distance_bin_edges_m": (6.0, math.inf)}, "distance_bin_edges_m"),
        ({"min_overlap_cells": 0}, "min_overlap_cells"),
        ({"border_band_m": -1.0}, "border_band_m"),
    ],
)
def test_config_validation(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        DetectionEvalConfig(**kwargs)


def test_eval_does_not_import_simulator() -> None:
    import subprocess
    import sys

    code = "import sys, negobs_gym.eval; print('pybullet' in sys.modules, 'gymnasium' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False False"
