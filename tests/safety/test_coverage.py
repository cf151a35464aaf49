"""Tests of the observed clear distance and the coverage memory on synthetic grids."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError
from negobs_gym.safety import Corridor, CoverageMemory, observed_clear_distance

GRID = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)  # the envs' detector grid
STRAIGHT = Corridor(steer_rad=0.0, wheelbase_m=2.8, half_width_m=1.2, front_length_m=3.65)
NO_HAZARDS = np.zeros((0, 2))


def _all_seen() -> np.ndarray:
    return np.ones(GRID.shape, dtype=bool)


def _unsee(observed: np.ndarray, x_m: float, y_m: float) -> np.ndarray:
    """``observed`` with the cell holding vehicle-frame point (x, y) unobserved."""
    row, col, inside = GRID.cell_of(np.array([x_m, y_m]))
    assert inside
    out = observed.copy()
    out[row, col] = False
    return out


def test_fully_observed_straight_corridor_is_clear_to_the_grids_range():
    clear = observed_clear_distance(STRAIGHT, GRID, _all_seen(), NO_HAZARDS)
    assert clear.end == "range" and clear.distance_m == pytest.approx(GRID.ahead_m)


def test_a_hole_of_unobserved_cells_ends_it_at_the_hole():
    observed = _all_seen()
    for x in (-0.3, -0.1, 0.1, 0.3):
        observed = _unsee(observed, x, 12.1)
    clear = observed_clear_distance(STRAIGHT, GRID, observed, NO_HAZARDS)
    assert clear.end == "unobserved" and clear.distance_m == pytest.approx(12.1)
    # counting unobserved cells as clear, only the range ends it
    relaxed = observed_clear_distance(STRAIGHT, GRID, observed, NO_HAZARDS, unobserved_blocks=False)
    assert relaxed.end == "range" and relaxed.distance_m == pytest.approx(GRID.ahead_m)


def test_holes_beside_the_corridor_or_under_the_car_do_not_count():
    observed = _unsee(_unsee(_all_seen(), 3.1, 8.1), 0.1, 2.1)  # 3.1 m to the side; under the bonnet
    clear = observed_clear_distance(STRAIGHT, GRID, observed, NO_HAZARDS)
    assert clear.end == "range"


def test_a_hazard_before_the_first_hole_ends_it_at_the_hazard():
    observed = _unsee(_all_seen(), 0.1, 15.1)
    hazards = np.array([[0.5, 9.1], [-3.0, 5.0]])  # the second lies beside the corridor
    clear = observed_clear_distance(STRAIGHT, GRID, observed, hazards)
    assert clear.end == "hazard" and clear.distance_m == pytest.approx(9.1)
    far_hazard = observed_clear_distance(STRAIGHT, GRID, observed, np.array([[0.0, 20.0]]))
    assert far_hazard.end == "unobserved" and far_hazard.distance_m == pytest.approx(15.1)


def test_the_steered_corridor_follows_the_arc():
    steer = math.radians(20.0)  # left: the turn centre at (-R, 0)
    turning = Corridor(steer_rad=steer, wheelbase_m=2.8, half_width_m=1.2, front_length_m=3.65)
    radius = 2.8 / math.tan(steer)
    theta = 8.0 / radius  # a hole on the rear-axle circle 8 m along the arc
    x, y = radius * math.cos(theta) - radius, radius * math.sin(theta)
    observed = _unsee(_all_seen(), x, y)
    clear = observed_clear_distance(turning, GRID, observed, NO_HAZARDS)
    assert clear.end == "unobserved" and clear.distance_m == pytest.approx(8.0, abs=0.15)
    # the straight corridor does not pass over that cell (it lies 1.6 m to the left at 7.8 m)
    assert observed_clear_distance(STRAIGHT, GRID, observed, NO_HAZARDS).end == "range"
    # all observed, the turning corridor leaves the grid by its side, well before 25.6 m of arc
    ring = observed_clear_distance(turning, GRID, _all_seen(), NO_HAZARDS)
    assert ring.end == "range" and 5.0 < ring.distance_m < GRID.ahead_m


def test_a_wrongly_shaped_layer_is_named():
    with pytest.raises(ConfigError, match="observed"):
        observed_clear_distance(STRAIGHT, GRID, np.ones((3, 3), dtype=bool), NO_HAZARDS)


def test_memory_carries_cells_with_the_pose_and_forgets_them_after_hold():
    stripe = np.zeros(GRID.shape, dtype=bool)
    row, _, _ = GRID.cell_of(np.array([0.0, 10.1]))
    stripe[row, :] = True  # the row of cells 10-10.2 m ahead
    memory = CoverageMemory(hold_s=1.0)
    start = Pose(x=5.0, y=-2.0, yaw=0.3)
    memory.add(0.0, start, stripe)
    # 2 m further along the heading: the stripe now lies 8-8.2 m ahead
    moved = Pose(x=5.0 - 2.0 * math.sin(0.3), y=-2.0 + 2.0 * math.cos(0.3), yaw=0.3)
    memory.add(0.5, moved, np.zeros(GRID.shape, dtype=bool))
    seen = memory.observed(GRID, moved, 0.5)
    rows = np.nonzero(seen[:, GRID.cols // 2])[0]
    assert rows.tolist() == [GRID.cell_of(np.array([0.0, 8.1]))[0]]
    assert seen.sum() == pytest.approx(GRID.cols, abs=2)
    assert not memory.observed(GRID, moved, 1.2).any()  # the stripe's frame is 1.2 s old
    cells = np.zeros(GRID.shape, dtype=bool)
    cells[rows[0], :5] = True
    cells[0, :] = True  # looked up, never seen
    only_some = memory.observed(GRID, moved, 0.5, cells=cells)
    assert only_some.sum() == 5 and only_some[rows[0], :5].all()
    with pytest.raises(ConfigError, match="cells"):
        memory.observed(GRID, moved, 0.5, cells=np.ones(5, dtype=bool))
