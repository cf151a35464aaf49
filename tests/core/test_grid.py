import warnings

import numpy as np
import pytest

from negobs_gym.core import GridSpec
from negobs_gym.errors import ConfigError, GeometryError


def test_default_grid_is_20cm_and_covers_25m_ahead_10m_each_side():
    g = GridSpec()
    assert g.cell_m == 0.2 and g.ahead_m >= 25 and g.side_m >= 10
    assert g.shape == (round((g.ahead_m + g.back_m) / 0.2), round(2 * g.side_m / 0.2))


def test_cell_of_and_cell_centres_agree():
    g = GridSpec(ahead_m=4.0, back_m=1.0, side_m=2.0)
    centres = g.cell_centres()
    row, col, inside = g.cell_of(centres.reshape(-1, 2))
    assert inside.all()
    rr, cc = np.meshgrid(np.arange(g.rows), np.arange(g.cols), indexing="ij")
    assert (row == rr.ravel()).all() and (col == cc.ravel()).all()
    # origin cell: row counts from the rear edge, col from the left edge
    r0, c0, _ = g.cell_of(np.array([0.01, 0.01]))
    assert (r0, c0) == (5, 10)
    _, _, out = g.cell_of(np.array([[0.0, 4.01], [-2.01, 0.0], [0.0, -1.01]]))
    assert not out.any()


def test_window_holds_the_cells_of_a_box_clipped_to_the_grid():
    g = GridSpec(ahead_m=4.0, back_m=1.0, side_m=2.0)
    rng = np.random.default_rng(2)
    for lo, size in zip(rng.uniform(-4.0, 5.0, (100, 2)), rng.uniform(0.0, 2.0, (100, 2)), strict=True):
        rows, cols = g.window(lo, lo + size)
        (r0, r1), (c0, c1), _ = g.cell_of(np.stack([lo, lo + size]))
        assert (rows.start, rows.stop) == (max(r0, 0), min(r1 + 1, g.rows))
        assert (cols.start, cols.stop) == (max(c0, 0), min(c1 + 1, g.cols))
    assert g.window(np.array([-0.9, 0.1]), np.array([0.9, 0.3])) == (slice(5, 7), slice(5, 15))
    rows, cols = g.window(np.array([3.0, 0.0]), np.array([4.0, 1.0]))  # beside the grid: no column
    assert cols.start >= cols.stop


def test_contains_is_cell_of_mask_with_nan_outside():
    g = GridSpec(ahead_m=4.0, back_m=1.0, side_m=2.0)
    pts = np.random.default_rng(1).uniform(-3.0, 5.0, (200, 2))
    pts[:6] = [[-2.0, -1.0], [2.0, 0.0], [0.0, 4.0], [0.0, -1.0], [1.99, 3.99], [np.nan, 0.0]]
    np.testing.assert_array_equal(g.contains(pts), g.cell_of(pts)[2])
    assert g.contains(pts[:6]).tolist() == [True, False, False, True, True, False]


@pytest.mark.parametrize("field", ["cell_m", "ahead_m", "side_m", "back_m"])
def test_invalid_grid_raises_config_error_naming_field(field):
    with pytest.raises(ConfigError, match=field):
        GridSpec(**{field: -1.0})


def test_occupied_marks_the_cells_of_the_points_inside_and_ignores_nan():
    grid = GridSpec(ahead_m=6.0, back_m=1.0, side_m=2.0)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-4.0, 8.0, (40, 30, 2))  # about a quarter inside
    pts[rng.random((40, 30)) < 0.3] = np.nan
    want = np.zeros(grid.shape, dtype=bool)
    ok = ~np.isnan(pts).any(axis=-1)
    row, col, inside = grid.cell_of(pts[ok])
    want[row[inside], col[inside]] = True
    np.testing.assert_array_equal(grid.occupied(pts), want)
    assert 0 < want.sum() < want.size
    assert not grid.occupied(np.full((5, 2), np.nan)).any()
    edge = np.array([[grid.side_m, 0.0], [-grid.side_m, 0.0]])  # the right edge is outside, the left inside
    assert grid.occupied(edge).sum() == 1


def test_occupied_reads_a_strided_view_of_scan_points_and_names_a_wrong_shape():
    grid = GridSpec(ahead_m=6.0, back_m=1.0, side_m=2.0)
    rng = np.random.default_rng(1)
    points = rng.uniform(-3.0, 7.0, (16, 50, 3))  # (lasers, columns, xyz) as a scan gives them
    points[rng.random((16, 50)) < 0.2] = np.nan
    view = points[..., :2]
    np.testing.assert_array_equal(grid.occupied(view), grid.occupied(np.ascontiguousarray(view)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # NaN points are no cell: no invalid cast
        row, col, inside = grid.cell_of(view.reshape(-1, 2))
    no_point = np.isnan(view.reshape(-1, 2)).any(axis=1)
    assert no_point.any() and (row[no_point] == -1).all() and (col[no_point] == -1).all()
    assert not inside[no_point].any()
    want = np.zeros(grid.shape, dtype=bool)
    want[row[inside], col[inside]] = True
    np.testing.assert_array_equal(grid.occupied(view), want)
    with pytest.raises(GeometryError, match=r"^xy: must have shape \(\.\.\., 2\)"):  # a ValueError too
        grid.occupied(points)


def test_extent_is_the_box_whose_points_fall_in_cells():
    grid = GridSpec(cell_m=0.2, ahead_m=4.0, back_m=1.0, side_m=2.0)
    x0, x1, y0, y1 = grid.extent_xy_m
    assert (x0, x1, y0, y1) == (-2.0, 2.0, -1.0, 4.0)
    eps = 1e-9
    inside = np.array([[x0, y0], [x1 - eps, y1 - eps], [0.5 * (x0 + x1), 0.5 * (y0 + y1)]])
    outside = np.array([[x0 - eps, 0.0], [x1, 0.0], [0.0, y0 - eps], [0.0, y1]])
    assert grid.cell_of(inside)[2].all()
    assert not grid.cell_of(outside)[2].any()


def test_centres_of_a_mask_are_those_cells_centres():
    grid = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)
    mask = np.random.default_rng(0).random(grid.shape) < 0.05
    assert np.array_equal(grid.centres_of(mask), grid.cell_centres()[mask])
    assert grid.centres_of(np.zeros(grid.shape, bool)).shape == (0, 2)


def test_carry_index_moves_a_layer_by_the_vehicles_motion():
    """Driving 3 cells forward moves a seen cell 3 rows nearer; cells that come into view are unseen."""
    from negobs_gym.core.grid import carry_layer
    from negobs_gym.core.pose import Pose

    grid = GridSpec(ahead_m=4.0, back_m=0.0, side_m=1.0)
    layer = np.zeros(grid.shape, dtype=bool)
    layer[15, 2] = True
    layer[0, 0] = True  # the row the car drives over: it leaves the grid
    seen_at = Pose(x=5.0, y=-2.0, yaw=0.0)
    now = Pose(x=5.0, y=-2.0 + 3 * grid.cell_m + 0.01, yaw=0.0)
    moved = carry_layer(layer, grid.carry_index(seen_at, now))
    assert moved.dtype == bool and moved.shape == grid.shape
    assert np.argwhere(moved).tolist() == [[12, 2]]
    assert not moved[-3:].any()  # the rows ahead that the earlier grid did not cover
    np.testing.assert_array_equal(carry_layer(layer, grid.carry_index(seen_at, seen_at)), layer)
    # the pose given as its cell centres in the world (shared by many grids carried into it)
    tilted = Pose(x=5.3, y=-1.1, z=0.2, roll=0.03, pitch=-0.02, yaw=0.4)
    for into in (now, tilted):
        np.testing.assert_array_equal(
            grid.carry_index(seen_at, grid.world_centres(into)), grid.carry_index(seen_at, into)
        )


def test_carry_follows_a_turn_and_agrees_with_carried_points():
    """After a 90 deg left turn on the spot a cell 1 m ahead lies 1 m to the right; the cell under a
    carried cell centre is the cell the carried layer sets."""
    from negobs_gym.core.grid import carry_layer, carry_points
    from negobs_gym.core.pose import Pose

    grid = GridSpec(ahead_m=3.0, back_m=3.0, side_m=3.0)
    layer = np.zeros(grid.shape, dtype=bool)
    ahead = np.array([[0.1, 1.1]])  # a cell centre 1.1 m ahead, 0.1 m right
    row, col, _ = grid.cell_of(ahead)
    layer[row[0], col[0]] = True
    seen_at, now = Pose(x=1.0, y=2.0, yaw=0.3), Pose(x=1.0, y=2.0, yaw=0.3 + np.pi / 2)
    moved = carry_layer(layer, grid.carry_index(seen_at, now))
    there = carry_points(ahead, seen_at, now)
    np.testing.assert_allclose(there, [[1.1, -0.1]], atol=1e-12)  # vehicle frame: x right, y forward
    r, c, inside = grid.cell_of(there)
    assert inside.all() and np.argwhere(moved).tolist() == [[r[0], c[0]]]
