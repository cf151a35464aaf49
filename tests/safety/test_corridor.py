import numpy as np

from negobs_gym.safety import hazard_distance_m


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
