"""Rate intervals and paired tests: against their closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.eval.stats import format_interval, paired_rate, paired_shift, rate_interval


def wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The Wilson score interval written out (Wilson 1927)."""
    p = k / n
    centre = p + z * z / (2 * n)
    spread = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (centre - spread) / (1 + z * z / n), (centre + spread) / (1 + z * z / n)


@pytest.mark.parametrize(("k", "n"), [(0, 1), (10, 10), (0, 20), (7, 20), (99, 100), (53, 100)])
def test_rate_interval_is_wilsons(k: int, n: int) -> None:
    low, high = rate_interval(k, n)
    assert (low, high) == pytest.approx(wilson(k, n), abs=1e-9)
    assert 0.0 <= low <= k / n <= high <= 1.0


def test_rate_interval_of_all_stops_stays_below_one() -> None:
    # 100 of 100 stops bound the rate from below at 0.963, not at 1.0
    assert format_interval(rate_interval(100, 100), 3) == "0.963-1.000"
    assert rate_interval(0, 0) is None and format_interval(None) == "-"
    assert rate_interval(7, 20, confidence=0.99)[0] < rate_interval(7, 20)[0]


@pytest.mark.parametrize(
    ("k", "n", "confidence", "field"),
    [(3, 2, 0.95, "successes"), (-1, 2, 0.95, "successes"), (1, 2, 1.0, "confidence")],
)
def test_rate_interval_refuses_impossible_counts(k: int, n: int, confidence: float, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        rate_interval(k, n, confidence)


def test_paired_rate_is_the_exact_mcnemar_test() -> None:
    # 7 seeds where only A reached the goal, 1 where only B did, 4 where both, 3 where neither
    a = [True] * 7 + [False] + [True] * 4 + [False] * 3
    b = [False] * 7 + [True] + [True] * 4 + [False] * 3
    r = paired_rate("goal", a, b)
    assert (r.pairs, r.a, r.b, r.a_only, r.b_only) == (15, 11, 5, 7, 1)
    assert r.difference == pytest.approx(6 / 15)
    assert r.p_value == pytest.approx(2 * (math.comb(8, 0) + math.comb(8, 1)) / 2**8)  # two-sided, 1/2
    swapped = paired_rate("goal", b, a)
    assert swapped.p_value == r.p_value and swapped.difference == -r.difference
    assert paired_rate("goal", [True, False], [True, False]).p_value == 1.0  # no seed tells them apart


def test_paired_shift_is_the_signed_rank_test() -> None:
    # six seeds, each better on A: the exact two-sided p of all ranks on one side is 2 / 2**6
    a = [10.0, 12.0, 15.0, 11.0, 30.0, 9.0]
    b = [9.0, 10.0, 11.0, 10.5, 20.0, 3.0]
    s = paired_shift("progress_m", a, b)
    assert s.pairs == 6 and s.p_value == pytest.approx(2 / 2**6)
    assert s.median_difference == pytest.approx(3.0)  # of 1, 2, 4, 0.5, 10, 6
    assert (s.median_a, s.median_b) == (pytest.approx(11.5), pytest.approx(10.25))
    # a pair with no finite value on one side is left out; equal pairs give no evidence
    s = paired_shift("gap", [1.0, math.inf, 2.0], [1.0, 3.0, math.nan])
    assert s.pairs == 1 and s.p_value == 1.0 and s.median_difference == 0.0


@pytest.mark.parametrize(
    ("a", "b", "match"),
    [([1.0], [1.0, 2.0], "one value per seed"), ([], [], "at least one seed"), ([math.nan], [1.0], "finite")],
)
def test_paired_tests_refuse_unpaired_values(a: list[float], b: list[float], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        paired_shift("gap", a, b)
    if match != "finite":
        with pytest.raises(ConfigError, match=match):
            paired_rate("goal", [x > 0 for x in a], [x > 0 for x in b])


def test_seed_bootstrap_narrows_with_more_courses_and_is_reproducible() -> None:
    from negobs_gym.eval.stats import seed_bootstrap_interval

    rng = np.random.default_rng(3)
    seen = rng.integers(5, 15, size=(6, 4)).astype(float)
    seen[:, 2] = 0  # a bin no course saw
    seen[1:, 3] = 0  # a bin one course saw
    hits = np.floor(seen * rng.uniform(0.2, 0.9, size=(6, 1)))  # each course its own recall
    low, high = seed_bootstrap_interval(hits, seen)
    assert np.isnan(low[2:]).all() and np.isnan(high[2:]).all()
    pooled = hits[:, :2].sum(0) / seen[:, :2].sum(0)
    assert np.all((low[:2] <= pooled) & (pooled <= high[:2]))
    again = seed_bootstrap_interval(hits, seen)
    np.testing.assert_array_equal(np.nan_to_num(low), np.nan_to_num(again[0]))  # deterministic
    # the same courses four times over: the spread of a mean of 4x the courses, about half as wide
    low4, high4 = seed_bootstrap_interval(np.tile(hits, (4, 1)), np.tile(seen, (4, 1)))
    ratio = (high4[:2] - low4[:2]) / (high[:2] - low[:2])
    assert np.all((ratio > 0.35) & (ratio < 0.7))


@pytest.mark.parametrize(
    ("hits", "seen", "match"),
    [
        (np.ones((3, 2)), np.ones((3, 3)), "like seen"),
        (np.ones((1, 2)), np.ones((1, 2)), "at least 2 seeds"),
        (np.full((3, 2), 2.0), np.ones((3, 2)), "0..seen"),
    ],
)
def test_seed_bootstrap_refuses_bad_counts(hits, seen, match: str) -> None:
    from negobs_gym.eval.stats import seed_bootstrap_interval

    with pytest.raises(ConfigError, match=match):
        seed_bootstrap_interval(hits, seen)
