import numpy as np
import pytest

from negobs_gym.detector import geometry as g


def test_ring_radius_and_range_hand_values():
    b = np.arctan2(10.0, 2.2)
    assert g.ring_radius(2.2, b) == pytest.approx(10.0)
    assert g.ground_range(2.2, b) == pytest.approx(np.hypot(10.0, 2.2))
    assert g.ring_radius(2.2, np.pi / 2 + 0.01) == np.inf
    assert g.nadir_angle_from_elevation(-np.pi / 2) == pytest.approx(0.0)


def test_radial_resolution_paper_fig3():
    # paper N §2.1: 2.2 m mount, dbeta 0.4 deg -> ring gap of a few tens of cm at 10 m
    # (h sec^2(beta) dbeta = 0.33 m; the paper quotes "close to 50 cm")
    b = np.arctan2(10.0, 2.2)
    gap = g.radial_resolution(2.2, b, np.radians(0.4))
    assert 0.3 < gap < 0.55
    assert gap == pytest.approx(10.0 - 2.2 * np.tan(b - np.radians(0.4)))


def test_lateral_resolution_and_subtended_angle():
    b = np.arctan2(16.0, 2.2)
    assert g.lateral_resolution(2.2, b, np.radians(2.0)) == pytest.approx(2 * 16 * np.sin(np.radians(1)))
    exact = g.subtended_angle(2.2, 20.0, 1.0)
    approx = g.subtended_angle_approx(2.2, 20.0, 1.0)
    assert exact == pytest.approx(np.arctan2(21.0, 2.2) - np.arctan2(20.0, 2.2))
    assert approx == pytest.approx(exact, rel=0.02)


def test_visible_height_paper_example_and_range_jump():
    assert g.visible_height_difference(2.2, 8.0, 0.6) == pytest.approx(0.165)
    b = np.arctan2(8.0, 2.2)
    dh = 0.6 * 2.2 / 8.0
    assert g.range_jump(0.6, b) == pytest.approx(np.hypot(0.6, dh))


def test_bad_height_rejected():
    with pytest.raises(ValueError, match="height_m"):
        g.ring_radius(-1.0, 0.5)
    with pytest.raises(ValueError, match="height_m"):
        g.ring_radius(np.nan, 0.5)
