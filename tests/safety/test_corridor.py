import numpy as np
import pytest

from negobs_gym.safety import Corridor, hazard_distance_m


def test_straight():
    pts = np.array([[0.0, 12.0], [3.0, 5.0], [0.5, -1.0], [-0.9, 8.0]])
    assert hazard_distance_m(pts, 0.0, 2.8, 1.0) == 8.0


def test_empty_is_inf():
    assert np.isposinf(hazard_distance_m(np.zeros((0, 2)), 0.3, 2.8, 1.0))


def test_left_turn_quarter_circle():
    radius = 2.8 / np.tan(0.3)
    # a point a quarter turn round the left circle: centre (-R, 0), point (-R, R)
    d = hazard_distance_m(np.array([[-radius, radius]]), 0.3, 2.8, 1.0)
    assert np.isclose(d, radius * np.pi / 2)
    # the same point is clear when turning right
    assert np.isposinf(hazard_distance_m(np.array([[-radius, radius]]), -0.3, 2.8, 1.0))
    assert np.isclose(hazard_distance_m(np.array([[radius, radius]]), -0.3, 2.8, 1.0), d)


def test_outer_front_corner_widens_the_corridor_in_a_turn_only():
    steer, wheelbase, half_width, front = 0.6, 2.8, 1.2, 3.65
    radius = wheelbase / np.tan(steer)
    outer = np.hypot(radius + half_width, front)  # the outer front corner's circle
    assert outer - (radius + half_width) > 0.8  # the gap the rear-axle band left open

    def at(r, theta):  # a point at radius r around the left turn's centre (-R, 0), angle theta
        return np.array([[r * np.cos(theta) - radius, r * np.sin(theta)]])

    beyond_band = at(0.5 * (radius + half_width + outer), np.pi / 3)
    assert np.isposinf(hazard_distance_m(beyond_band, steer, wheelbase, half_width))
    d = hazard_distance_m(beyond_band, steer, wheelbase, half_width, front)
    assert np.isclose(d, radius * np.pi / 3)  # radial projection onto the rear-axle circle
    assert np.isposinf(hazard_distance_m(at(outer + 0.01, np.pi / 3), steer, wheelbase, half_width, front))
    inner = at(radius - half_width - 0.01, np.pi / 3)  # the inner side is the rear axle's: unchanged
    assert np.isposinf(hazard_distance_m(inner, steer, wheelbase, half_width, front))
    # the straight path is the rectangle swept forward: its width does not grow
    pts = np.array([[1.3, 5.0], [1.1, 9.0]])
    assert hazard_distance_m(pts, 0.0, wheelbase, half_width, front) == 9.0


def test_a_point_at_the_outer_front_corner_is_inside_now():
    radius = 2.8 / np.tan(0.6)
    corner = np.array([[-1.19, 3.6]])  # just inside the front left corner, the outer one turning right
    assert np.isposinf(hazard_distance_m(corner, -0.6, 2.8, 1.2))  # beyond the rear-axle band
    d = hazard_distance_m(corner, -0.6, 2.8, 1.2, 3.65)
    assert np.isclose(d, radius * np.arctan2(3.6, radius + 1.19))


def test_a_point_beside_the_outer_rear_is_never_reached():
    """Found by the filter's property test: steering 0.25 of 35 deg, a point 1.25 m to the right
    and 1 m ahead of the rear axle, just outside the 1.2 m half-width. The ring counted it, but
    only the car's front passes beyond its outer side, from the angle where that side meets the
    point's radius, and the car turns away from it."""
    steer, wheelbase, half_width, front = 0.25 * np.deg2rad(35.0), 2.8, 1.2, 3.65
    radius = wheelbase / np.tan(steer)
    beside = np.array([[1.25, 1.0]])  # x right: the outer side of a left turn
    d = hazard_distance_m(beside, steer, wheelbase, half_width, front)
    assert d > 2.0 * np.pi * radius  # reached only after a full turn
    # the same radius further round is reached: where the outer side meets it, and beyond
    r = np.hypot(radius + 1.25, 1.0)
    entry = np.arctan2(np.sqrt(r**2 - (radius + half_width) ** 2), radius + half_width)
    for theta in (entry + 1e-6, entry + 0.1):
        point = np.array([[r * np.cos(theta) - radius, r * np.sin(theta)]])  # about the centre (-R, 0)
        assert np.isclose(hazard_distance_m(point, steer, wheelbase, half_width, front), radius * theta)


def test_a_point_on_the_outer_side_at_its_entry_angle_is_reached_now():
    """Found by the filter's property test: full left lock, a point on the body's right side 1.125 m
    ahead of the rear axle (x = the half-width). Its angle equals the entry angle where the outer
    side meets its radius, and round-off had put it just below, a full turn later (26 m)."""
    steer, wheelbase, half_width, front = np.deg2rad(35.0), 2.8, 1.1, 3.0
    radius = wheelbase / np.tan(steer)
    d = hazard_distance_m(np.array([[1.1, 1.125]]), steer, wheelbase, half_width, front)
    assert np.isclose(d, radius * np.arctan2(1.125, radius + 1.1))  # reached at once, not a turn later


CAR = {"wheelbase_m": 2.8, "half_width_m": 1.1, "front_length_m": 3.65}


@pytest.mark.parametrize("steer", [0.0, 0.15, -0.15, 0.6, -0.6])
@pytest.mark.parametrize("arc_m", [0.5, 2.0, 7.5, 14.0])
def test_the_drawn_cross_section_is_where_the_filter_puts_arc_m(steer, arc_m):
    corridor = Corridor(steer_rad=steer, **CAR)
    ends = corridor.reached_at_xy_m(arc_m)
    t = np.linspace(0.02, 0.98, 25)[:, None]
    inside = ends[0] + t * (ends[1] - ends[0])
    for p in inside:
        assert corridor.hazard_distance_m(p) == pytest.approx(arc_m, rel=1e-9, abs=1e-9)
    # past the far end: outside the corridor, or reached only later (the front sweeps it after)
    beyond = ends[1] + 0.05 * (ends[1] - ends[0]) / np.linalg.norm(ends[1] - ends[0])
    assert corridor.hazard_distance_m(beyond) > arc_m + 1e-6


def test_the_cross_section_is_cut_where_the_front_has_not_yet_swept():
    corridor = Corridor(steer_rad=0.6, **CAR)
    radius = CAR["wheelbase_m"] / np.tan(0.6)
    ends = corridor.reached_at_xy_m(1.0)  # 1 m of arc: the outer front corner's circle not yet reached
    r_far = np.hypot(ends[1, 0] + radius, ends[1, 1])
    assert (
        radius + CAR["half_width_m"] < r_far < np.hypot(radius + CAR["half_width_m"], CAR["front_length_m"])
    )
    far = corridor.reached_at_xy_m(10.0)
    assert np.hypot(far[1, 0] + radius, far[1, 1]) == pytest.approx(
        np.hypot(radius + CAR["half_width_m"], CAR["front_length_m"])
    )


@pytest.mark.parametrize("steer", [0.0, 0.3, -0.3])
def test_the_sides_bound_the_rear_axle_band(steer):
    corridor = Corridor(steer_rad=steer, **CAR)
    inner, outer = corridor.sides_xy_m(12.0, samples=40)
    arc = np.linspace(0.0, 12.0, 40)
    midpoint = 0.5 * (inner + outer)  # the rear axle's path: in the corridor at its arc length
    got = [corridor.hazard_distance_m(p) for p in midpoint[1:]]
    assert np.allclose(got, arc[1:], rtol=1e-9, atol=1e-9)
    assert np.allclose(np.linalg.norm(outer - inner, axis=1), 2 * CAR["half_width_m"])
    just_outside = outer + 0.01 * (outer - inner)  # beside the outer rear: not before a whole turn
    assert corridor.hazard_distance_m(just_outside[0]) > 12.0
    if steer > 0:  # a left turn bends towards -X
        assert inner[-1, 0] < 0 and outer[-1, 0] < 0
    assert corridor.hazard_distance_m(np.array([0.0, 5.0])) == hazard_distance_m(
        np.array([[0.0, 5.0]]), steer, CAR["wheelbase_m"], CAR["half_width_m"], CAR["front_length_m"]
    )
