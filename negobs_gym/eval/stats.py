"""How far a campaign's figures can be trusted: intervals on rates, paired tests between campaigns.

A campaign's episodes are independent draws: each seed builds its own course and draws its own
sensor noise. A rate over them (goals, entries, stops before the obstacle) is a binomial
proportion, given with its Wilson score interval, which keeps its coverage near 0 and 1 where the
normal approximation does not (10/10 stops: 0.72-1.00, not 1.00-1.00). Two campaigns on the same
seeds (two policies, a policy with and without the filter, two observation settings) meet the
same courses, so they are compared episode against episode: an outcome by the exact McNemar test
(the episodes where only one of them succeeded, against an even split), a measure such as
progress by the Wilcoxon signed-rank test of the per-seed differences. Both come from scipy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from negobs_gym.errors import require

__all__ = [
    "CONFIDENCE",
    "PairedRate",
    "PairedShift",
    "format_interval",
    "interval_list",
    "nan_to_none",
    "paired_rate",
    "paired_shift",
    "rate_interval",
    "seed_bootstrap_difference",
    "seed_bootstrap_interval",
]

CONFIDENCE = 0.95  # the level of every interval a campaign reports
BOOTSTRAP_RESAMPLES = 2000  # resamples of seed_bootstrap_interval: percentiles stable to ~0.01


def rate_interval(successes: int, trials: int, confidence: float = CONFIDENCE) -> tuple[float, float] | None:
    """The Wilson score interval of ``successes`` of ``trials``; None when there are no trials.

    Raises:
        ConfigError: counts outside 0 <= successes <= trials, or confidence outside (0, 1).
    """
    from scipy.stats import binomtest

    require(0 <= successes <= trials, "successes", f"must lie in 0..trials ({trials}), got {successes}")
    require(0.0 < confidence < 1.0, "confidence", f"must lie in (0, 1), got {confidence}")
    if trials == 0:
        return None
    ci = binomtest(successes, trials).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def seed_bootstrap_interval(
    hits: np.ndarray,
    seen: np.ndarray,
    *,
    confidence: float = CONFIDENCE,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Percentile interval of a pooled rate per column (``hits.sum(0) / seen.sum(0)``), resampling
    the rows (seeds) with replacement.

    A detection campaign's frames are not independent draws: one course's consecutive frames see
    the same pit from nearly the same place, so a binomial interval over frames would be far too
    narrow. Its seeds are independent, so they are what is resampled (a cluster bootstrap). A
    resample that saw nothing in a column is dropped for that column; a column seen by fewer than
    two seeds is NaN (one seed's rate resampled is that rate again: no interval). Deterministic for
    a given ``seed``.

    Raises:
        ConfigError: shapes that differ or are not 2-D, negative counts, hits above seen, or fewer
            than 2 rows.
    """
    hits, seen = _counts(hits, seen)
    rows = _resampled_rows(hits.shape[0], confidence, resamples, seed)
    return _percentiles(_pooled_rate(hits, seen, rows), _seen_twice(seen), confidence)


def seed_bootstrap_difference(
    a: tuple[np.ndarray, np.ndarray],
    b: tuple[np.ndarray, np.ndarray],
    *,
    confidence: float = CONFIDENCE,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pooled rate of ``a`` minus that of ``b`` per column, each a ``(hits, seen)`` pair whose
    rows are the same seeds, and its percentile interval from resampling the seeds together (a
    paired cluster bootstrap: a seed's course counts on both sides or on neither). NaN where fewer
    than two seeds saw the column on either side.

    Raises:
        ConfigError: as :func:`seed_bootstrap_interval`, or sides of different shapes.
    """
    (hits_a, seen_a), (hits_b, seen_b) = _counts(*a), _counts(*b)
    require(
        hits_a.shape == hits_b.shape,
        "b",
        f"must be (seeds, bins) like a, got {hits_b.shape} and {hits_a.shape}",
    )
    rows = _resampled_rows(hits_a.shape[0], confidence, resamples, seed)
    every = np.arange(hits_a.shape[0])[None, :]
    difference = _pooled_rate(hits_a, seen_a, every)[0] - _pooled_rate(hits_b, seen_b, every)[0]
    resampled = _pooled_rate(hits_a, seen_a, rows) - _pooled_rate(hits_b, seen_b, rows)
    enough = _seen_twice(seen_a) & _seen_twice(seen_b)
    low, high = _percentiles(resampled, enough, confidence)
    return np.where(enough, difference, np.nan), low, high


def _counts(hits: np.ndarray, seen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    hits, seen = np.asarray(hits, dtype=float), np.asarray(seen, dtype=float)
    require(
        hits.ndim == 2 and hits.shape == seen.shape,
        "hits",
        f"must be (seeds, bins) like seen, got {hits.shape} and {seen.shape}",
    )
    require(hits.shape[0] >= 2, "hits", f"needs at least 2 seeds to resample, got {hits.shape[0]}")
    require(bool(np.all((hits >= 0) & (hits <= seen))), "hits", "must lie in 0..seen in every cell")
    return hits, seen


def _resampled_rows(n: int, confidence: float, resamples: int, seed: int) -> np.ndarray:
    require(0.0 < confidence < 1.0, "confidence", f"must lie in (0, 1), got {confidence}")
    return np.random.default_rng(seed).integers(0, n, size=(resamples, n))


def _pooled_rate(hits: np.ndarray, seen: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Per resample (row of ``rows``) and column, the pooled rate; NaN where it saw nothing."""
    pooled_seen = seen[rows].sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(pooled_seen > 0, hits[rows].sum(axis=1) / pooled_seen, np.nan)


def _seen_twice(seen: np.ndarray) -> np.ndarray:
    return np.count_nonzero(seen > 0, axis=0) >= 2


def _percentiles(values: np.ndarray, columns: np.ndarray, confidence: float) -> tuple[np.ndarray, np.ndarray]:
    tail = 50.0 * (1.0 - confidence)
    low, high = np.full(values.shape[1], np.nan), np.full(values.shape[1], np.nan)
    if columns.any():
        low[columns], high[columns] = np.nanpercentile(values[:, columns], [tail, 100.0 - tail], axis=0)
    return low, high


def interval_list(low: np.ndarray, high: np.ndarray) -> list[list[float] | None]:
    """Per column ``[low, high]`` as plain floats for JSON; None where there is no interval (NaN)."""
    return [None if np.isnan(lo) else [float(lo), float(hi)] for lo, hi in zip(low, high, strict=True)]


def nan_to_none(values: np.ndarray) -> list[float | None]:
    """``values`` as plain floats for JSON; None for NaN and infinities."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=float).ravel()]


def format_interval(interval: tuple[float, float] | None, digits: int = 2) -> str:
    """``0.08-0.42``; ``-`` for None (no trials)."""
    return "-" if interval is None else f"{interval[0]:.{digits}f}-{interval[1]:.{digits}f}"


@dataclass(frozen=True)
class PairedRate:
    """An outcome of two campaigns on their common seeds: how often each had it, and the test."""

    name: str
    pairs: int
    a: int  # episodes of A with the outcome
    b: int
    a_only: int  # seeds where A had it and B did not
    b_only: int
    p_value: float  # exact McNemar (two-sided); 1.0 when no seed tells them apart

    @property
    def difference(self) -> float:
        """A's rate minus B's on the paired seeds."""
        return (self.a - self.b) / self.pairs


@dataclass(frozen=True)
class PairedShift:
    """A measure of two campaigns on the seeds where both have it: medians and the test."""

    name: str
    pairs: int
    median_a: float
    median_b: float
    median_difference: float  # the median of the per-seed differences A - B
    p_value: float  # Wilcoxon signed-rank (two-sided), zero differences dropped; 1.0 when all are zero


def paired_rate(name: str, a: Sequence[bool], b: Sequence[bool]) -> PairedRate:
    """Compare a yes/no outcome seed by seed (``a[i]`` and ``b[i]``: the same seed).

    Raises:
        ConfigError: the two sequences differ in length or are empty.
    """
    from scipy.stats import binomtest

    _check_pairs(name, len(a), len(b))
    x, y = np.asarray(a, dtype=bool), np.asarray(b, dtype=bool)
    a_only, b_only = int(np.sum(x & ~y)), int(np.sum(~x & y))
    discordant = a_only + b_only
    p = 1.0 if discordant == 0 else float(binomtest(a_only, discordant, 0.5).pvalue)
    return PairedRate(name, len(x), int(x.sum()), int(y.sum()), a_only, b_only, p)


def paired_shift(name: str, a: Sequence[float], b: Sequence[float]) -> PairedShift:
    """Compare a measure seed by seed; pairs where either value is not finite are left out (a
    braking gap of an episode that never saw the obstacle).

    Raises:
        ConfigError: the two sequences differ in length, or no pair is finite on both sides.
    """
    from scipy.stats import wilcoxon

    _check_pairs(name, len(a), len(b))
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    finite = np.isfinite(x) & np.isfinite(y)
    require(bool(finite.any()), name, "no seed where both campaigns have a finite value")
    x, y = x[finite], y[finite]
    d = x - y
    p = 1.0 if not np.any(d != 0) else float(wilcoxon(d, zero_method="wilcox").pvalue)
    return PairedShift(name, int(d.size), float(np.median(x)), float(np.median(y)), float(np.median(d)), p)


def _check_pairs(name: str, n_a: int, n_b: int) -> None:
    require(n_a == n_b, name, f"needs one value per seed on both sides, got {n_a} and {n_b}")
    require(n_a > 0, name, "needs at least one seed on both sides")
