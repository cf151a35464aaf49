"""Scalar Kalman filters with F = H = I, u = 0 (paper T §3.2)."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.detector.traversable.kalman import BoundaryKalman


def test_first_measurement_initialises_then_converges() -> None:
    kf = BoundaryKalman((2,), measurement_var=1.0, process_var=0.01)
    assert np.isnan(kf.update(np.array([np.nan, np.nan]))).all()
    assert kf.update(np.array([5.0, np.nan])) == pytest.approx([5.0, np.nan], nan_ok=True)
    for _ in range(200):
        est = kf.update(np.array([7.0, 1.0]))
    assert est == pytest.approx([7.0, 1.0], abs=1e-3)


def test_gain_matches_scalar_recursion() -> None:
    r, q = 0.5, 0.1
    kf = BoundaryKalman((1,), r, q)
    kf.update(np.array([0.0]))
    p = r
    x = 0.0
    for z in (1.0, -0.5, 2.0):
        p += q
        k = p / (p + r)
        x += k * (z - x)
        p *= 1 - k
        assert kf.update(np.array([z]))[0] == pytest.approx(x, rel=1e-12)
    assert kf.variance[0] == pytest.approx(p)


def test_missing_measurement_only_predicts() -> None:
    kf = BoundaryKalman((1,), 1.0, 0.2)
    kf.update(np.array([3.0]))
    before = kf.variance.copy()
    assert kf.update(np.array([np.nan]))[0] == 3.0
    assert kf.variance[0] == pytest.approx(before[0] + 0.2)


def test_white_noise_variance_reduced() -> None:
    rng = np.random.default_rng(1)
    kf = BoundaryKalman((1,), 0.09, 0.01)
    z = rng.normal(0.0, 0.3, size=2000)
    est = np.array([kf.update(np.array([v]))[0] for v in z])
    assert est[100:].var() / z[100:].var() < 0.3


def test_shape_mismatch_and_reset() -> None:
    kf = BoundaryKalman((2, 3), 1.0, 1.0)
    with pytest.raises(ValueError, match="shape"):
        kf.update(np.zeros(3))
    kf.update(np.ones((2, 3)))
    kf.reset()
    assert np.isnan(kf.state).all()


def test_gate_holds_back_a_lateral_jump_then_restarts() -> None:
    kf = BoundaryKalman((1, 2), 0.09, 0.01)
    kf.update(np.array([[-4.0, 9.0]]))
    z = kf.gate_points(np.array([[-1.0, 9.5]]), gate_x_m=1.0, reset_after=3)
    assert np.isnan(z).all()  # x jumped 3 m: dropped (x and y together)
    kf.update(z)
    assert kf.state[0, 0] == -4.0
    z = kf.gate_points(np.array([[-4.2, 10.5]]), gate_x_m=1.0, reset_after=3)
    assert np.array_equal(z, [[-4.2, 10.5]])  # y is never gated; small x change passes
    for _ in range(2):
        kf.update(kf.gate_points(np.array([[-1.0, 9.0]]), 1.0, 3))
        assert kf.state[0, 0] < -3.5
    kf.update(kf.gate_points(np.array([[-1.0, 9.0]]), 1.0, 3))  # third in a row: restart
    assert kf.state[0, 0] == -1.0


def test_carry_points_replaces_estimates_and_keeps_the_unseen_unseen() -> None:
    kf = BoundaryKalman((2, 2), 0.09, 0.01)
    kf.update(np.array([[1.0, 5.0], [np.nan, np.nan]]))
    kf.variance[0] = [0.09, 0.2]
    kf.carry_points(np.array([[1.5, 5.0], [np.nan, np.nan]]))
    assert kf.state[0] == pytest.approx([1.5, 5.0])
    assert np.isnan(kf.state[1]).all() and np.isinf(kf.variance[1]).all()
    assert kf.variance[0] == pytest.approx([0.2, 0.2])
    kf.update(np.array([[2.0, 5.0], [3.0, 6.0]]))  # the unseen point starts at its measurement
    assert kf.state[1] == pytest.approx([3.0, 6.0])


def test_carry_points_needs_point_estimates_of_its_shape() -> None:
    with pytest.raises(ValueError, match="carry_points"):
        BoundaryKalman((3,), 1.0, 1.0).carry_points(np.zeros(3))
    with pytest.raises(ValueError, match="carry_points"):
        BoundaryKalman((3, 2), 1.0, 1.0).carry_points(np.zeros((2, 2)))
