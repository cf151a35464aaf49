import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.detector.grid import convex_overlap_mask, obstacle_grid

GRID = GridSpec()


def _square(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def test_cell_aligned_square_marks_exactly_its_cells():
    mask = convex_overlap_mask(_square(0.0, 8.0, 1.0, 9.0), GRID)
    # touching neighbours share only an edge; the strict test keeps them out
    shrunk = convex_overlap_mask(_square(0.001, 8.001, 0.999, 8.999), GRID)
    assert shrunk.sum() == 25
    rows, cols = np.nonzero(shrunk)
    centres = GRID.cell_centres()[rows, cols]
    assert centres[:, 0].min() == pytest.approx(0.1) and centres[:, 1].max() == pytest.approx(8.9)
    assert mask.sum() >= 25


def test_offset_square_marks_every_overlapped_cell():
    # 1 m square shifted half a cell: it overlaps 6 x 6 cells
    assert convex_overlap_mask(_square(0.1, 8.1, 1.1, 9.1), GRID).sum() == 36


def test_thin_diagonal_strip_marks_cells_its_centres_miss():
    strip = np.array([[0.0, 8.0], [1.0, 9.0], [0.98, 9.02], [-0.02, 8.02]])
    mask = convex_overlap_mask(strip, GRID)
    centre_inside = GRID.cell_centres()
    assert mask.sum() >= 5  # a 1.4 m diagonal crosses at least five 20 cm cells
    assert not np.isnan(centre_inside).any()


def test_winding_does_not_matter_and_outside_is_empty():
    sq = _square(-0.3, 5.0, 0.3, 5.6)
    np.testing.assert_array_equal(convex_overlap_mask(sq, GRID), convex_overlap_mask(sq[::-1], GRID))
    assert not convex_overlap_mask(_square(50, 50, 51, 51), GRID).any()


def test_obstacle_grid_unions_outlines():
    a, b = _square(0, 8, 1, 9), _square(-3, 12, -2, 13)
    grid = obstacle_grid([a, b], GRID)
    assert grid.sum() == convex_overlap_mask(a, GRID).sum() + convex_overlap_mask(b, GRID).sum()
    assert not obstacle_grid([], GRID).any()


@pytest.mark.parametrize("poly", [np.zeros((2, 2)), np.full((4, 2), np.nan), np.zeros((4, 3))])
def test_bad_outline(poly):
    with pytest.raises(ValueError, match="outline_xy_m"):
        convex_overlap_mask(poly, GRID)
