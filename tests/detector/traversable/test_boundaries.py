"""Least-squares boundary lines (paper T §3.2)."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.core import Pose
from negobs_gym.detector.traversable import BoundaryLine, fit_boundary
from negobs_gym.detector.traversable.boundaries import carry_along_line, passes_on_its_side


def test_fit_recovers_line_and_ignores_nan_rows() -> None:
    y = np.array([9.0, 10.0, 11.5, np.nan])
    x = 0.3 * y - 4.0
    line = fit_boundary(np.column_stack([x, y]))
    assert line.slope == pytest.approx(0.3) and line.offset_m == pytest.approx(-4.0)
    assert line.x_at(10.0) == pytest.approx(-1.0)


def test_fit_degenerate_cases() -> None:
    assert fit_boundary(np.full((3, 2), np.nan)) is None
    assert fit_boundary(np.zeros((0, 2))) is None
    one = fit_boundary(np.array([[2.0, 9.0]]))
    assert one == BoundaryLine(0.0, 2.0)
    same_y = fit_boundary(np.array([[1.0, 9.0], [3.0, 9.0]]))
    assert same_y == BoundaryLine(0.0, 2.0)


def test_distance_is_perpendicular() -> None:
    line = BoundaryLine(1.0, 0.0)  # x = y
    assert line.distance(np.array([1.0, 0.0])) == pytest.approx(np.sqrt(0.5))


def test_drop_inconsistent_needs_a_majority() -> None:
    from negobs_gym.detector.traversable.boundaries import drop_inconsistent

    pts = np.array([[-4.0, 9.0], [-1.2, 10.0], [-4.1, 11.0]])
    out = drop_inconsistent(pts, 1.0)
    assert np.isnan(out[1]).all() and np.array_equal(out[[0, 2]], pts[[0, 2]])
    two = np.array([[-4.0, 9.0], [-1.2, 10.0], [np.nan, np.nan]])
    assert np.array_equal(drop_inconsistent(two, 1.0), two, equal_nan=True)


def test_carried_points_stay_on_the_road_edge_at_their_distance() -> None:
    """A straight edge x = 0.1 y - 4 seen at 6, 8 and 9.7 m; the car drives 1.5 m on, 0.4 m left,
    turning 8 deg left: the carried points keep their y and lie on that same edge in the world."""
    line = BoundaryLine(0.1, -4.0)
    y = np.array([6.0, 8.0, 9.7, np.nan])
    points = np.column_stack([line.x_at(y), y])
    before, after = Pose(x=2.0, y=1.0, yaw=0.3), Pose(x=1.6, y=2.5, yaw=0.3 + np.radians(8.0))
    carried = carry_along_line(points, line, before, after)
    assert carried[:3, 1] == pytest.approx(y[:3])
    assert np.isnan(carried[3]).all()
    world = after.to_world(np.column_stack([carried[:3], np.zeros(3)]))
    edge = before.to_world(np.array([[line.x_at(0.0), 0.0, 0.0], [line.x_at(20.0), 20.0, 0.0]]))
    along = (edge[1] - edge[0])[:2] / np.linalg.norm((edge[1] - edge[0])[:2])
    offset = world[:, :2] - edge[0, :2]
    assert offset[:, 0] * along[1] - offset[:, 1] * along[0] == pytest.approx(np.zeros(3), abs=1e-9)
    assert (carried[:3, 0] > points[:3, 0]).all()  # a left turn moves a left edge right in the car's frame


def test_carry_without_a_line_follows_the_old_heading_and_refuses_a_crosswise_edge() -> None:
    points = np.array([[-4.0, 8.0]])
    ahead = carry_along_line(points, None, Pose(), Pose(y=2.0))
    assert ahead == pytest.approx(points)  # driving straight along the edge changes nothing
    turned = carry_along_line(points, None, Pose(), Pose(yaw=np.radians(80.0)))
    assert np.isnan(turned).all()
    assert np.isfinite(carry_along_line(points, None, Pose(), Pose(yaw=np.radians(50.0)))).all()
    assert np.isnan(carry_along_line(points, None, Pose(), Pose(yaw=0.9), max_angle_deg=45.0)).all()


def test_a_boundary_passes_the_sensor_on_its_own_side_by_the_clearance() -> None:
    leaning_right = BoundaryLine(slope=0.5, offset_m=-3.0)  # x = -1 m at the sensor 4 m ahead
    sensor = (0.0, 4.0)
    assert passes_on_its_side(leaning_right, -1, sensor, 0.0)
    assert passes_on_its_side(leaning_right, -1, sensor, 1.0)
    assert not passes_on_its_side(leaning_right, -1, sensor, 1.5)
    assert not passes_on_its_side(leaning_right, +1, sensor, 0.0)  # as a right boundary: left of it
    assert passes_on_its_side(leaning_right, +1, sensor, -1.0)  # a negative clearance lets it cross
    assert not passes_on_its_side(leaning_right, -1, (-2.0, 4.0), 0.0)  # a sensor left of the line
