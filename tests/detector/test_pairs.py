import numpy as np
import pytest

from negobs_gym.detector.pairs import FeaturePairs, close_pairs, overlap_distance
from negobs_gym.errors import GeometryError


def _seg(*xy):
    return np.atleast_2d(np.asarray(xy, dtype=float))


def test_parallel_overlapping_pairs_are_their_lateral_offset_apart():
    # two radial pairs 5 cm apart sideways; one starts a ring later (A jumped to the next laser)
    d = overlap_distance(_seg(0.0, 7.6), _seg(0.0, 9.1), _seg(0.05, 7.9), _seg(0.05, 9.0))
    assert d[0] == pytest.approx(0.05)


def test_distance_is_symmetric_and_ignores_pair_direction():
    a1, b1, a2, b2 = _seg(0.0, 8.0), _seg(0.2, 9.0), _seg(0.3, 8.2), _seg(0.1, 9.3)
    d12 = overlap_distance(a1, b1, a2, b2)[0]
    assert overlap_distance(a2, b2, a1, b1)[0] == pytest.approx(d12)
    assert overlap_distance(b1, a1, a2, b2)[0] == pytest.approx(d12)


def test_pairs_in_line_without_overlap_measure_their_nearest_ends():
    d = overlap_distance(_seg(0.0, 8.0), _seg(0.0, 9.0), _seg(0.0, 9.3), _seg(0.0, 10.0))
    assert d[0] == pytest.approx(0.3)


def test_crossing_angle_uses_both_overlap_ends():
    # segments meeting at the near end and 0.2 m apart at the far end: mean 0.1 m
    d = overlap_distance(_seg(0.0, 8.0), _seg(-0.1, 9.0), _seg(0.0, 8.0), _seg(0.1, 9.0))
    assert d[0] == pytest.approx(0.1, abs=1e-3)


def test_close_pairs_matches_brute_force():
    rng = np.random.default_rng(3)
    a1 = rng.uniform(-3, 3, (60, 2))
    b1 = a1 + rng.uniform(-1, 1, (60, 2))
    a2 = rng.uniform(-3, 3, (50, 2))
    b2 = a2 + rng.uniform(-1, 1, (50, 2))
    i, j, d = close_pairs(a1, b1, a2, b2, 0.4)
    ii, jj = np.meshgrid(np.arange(60), np.arange(50), indexing="ij")
    full = overlap_distance(a1[ii.ravel()], b1[ii.ravel()], a2[jj.ravel()], b2[jj.ravel()]).reshape(60, 50)
    expected = set(zip(*np.nonzero(full <= 0.4), strict=True))
    assert set(zip(i.tolist(), j.tolist(), strict=True)) == expected
    assert expected  # the random layout does produce close pairs
    np.testing.assert_allclose(d, full[i, j])
    limit = rng.uniform(0.1, 0.4, 50)  # one maximum per pair of set 2
    i, j, d = close_pairs(a1, b1, a2, b2, limit)
    assert set(zip(i.tolist(), j.tolist(), strict=True)) == set(zip(*np.nonzero(full <= limit), strict=True))
    np.testing.assert_array_equal(d, full[i, j])


def test_close_pairs_of_empty_sets():
    i, j, d = close_pairs(np.empty((0, 2)), np.empty((0, 2)), _seg(0, 1), _seg(0, 2), 0.4)
    assert i.size == j.size == d.size == 0


def test_feature_pairs_reject_mismatched_rows():
    with pytest.raises(ValueError, match="same number of rows"):
        FeaturePairs("hdl64", np.zeros((2, 3)), np.zeros((3, 3)), np.zeros((2, 3)))


def test_overlap_distance_refuses_segment_sets_of_different_lengths():
    two = np.zeros((2, 2))
    with pytest.raises(GeometryError, match=r"^overlap_distance: segments a1-b1 have 2 rows, a2-b2 1"):
        overlap_distance(two, two + 1.0, two[:1], two[:1] + 1.0)
