"""Bayesian multi-sensor, multi-frame fusion of feature point pairs (paper N §3.3, Eq. 15-16).

History pairs are stored in the world frame (INS pose) and moved into the current vehicle frame each
frame. Pair-to-pair distance: paper N's overlap distance in the ground plane
(:func:`negobs_gym.detector.pairs.overlap_distance`), which stays put when the rings sweep over the
rim as the vehicle moves or pitches. A history pair matched (within ``match_distance_m``, d_min; for
the side HDL-32s' pairs beyond ``match_full_range_m`` a range-scaled d_min, see :class:`FusionConfig`)
by a sensor gets that sensor's Bayes hit update (Eq. 15); one matched by no sensor gets the miss
update (Eq. 16). Current pairs farther than d_min from every history pair enter with ``prior``
followed by their sensor's hit update.

Default arithmetic (odds form, odds = p / (1 - p)): prior 0.5 -> odds 1; hit likelihood ratio
0.6 / 0.2 = 3; confirm 0.95 -> odds 19. Two hits: 9 < 19 (not confirmed); three hits (three frames of
one sensor, or three sensors in one frame): 27 >= 19 (confirmed) — paper N §4.2.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from negobs_gym.core import Pose
from negobs_gym.detector.pairs import FeaturePairs, close_pairs, range_scale
from negobs_gym.errors import ConfigError, ScanError, require


@dataclass(frozen=True, kw_only=True)
class SensorLikelihood:
    """p(z | obstacle) and p(z | no obstacle) of one sensor (paper N Eq. 15)."""

    p_hit_given_obstacle: float = 0.6
    p_hit_given_free: float = 0.2

    def __post_init__(self) -> None:
        require(0.0 < self.p_hit_given_obstacle < 1.0, "p_hit_given_obstacle", "must be in (0, 1)")
        require(0.0 < self.p_hit_given_free < 1.0, "p_hit_given_free", "must be in (0, 1)")


@dataclass(frozen=True, kw_only=True)
class FusionConfig:
    """Fusion thresholds (paper N §3.3)."""

    match_distance_m: float = 0.10  # d_min, paper N §3.3
    # A history pair is hit by a frame pair of a ``range_scaled_sensors`` sensor farther than this
    # from the vehicle within d_min * range / this (at most max_match_scale times d_min); the frame
    # pair still enters the history unless it lies within d_min itself (documented deviation, the
    # paper's d_min is fixed). A pit's pairs run from A (last ground return before it) to B (first on
    # its back wall), where the scan lines cross it; the side HDL-32s sample the ground radially
    # every d^2 * 0.16 deg / h (0.45 m at 18 m), so a far pit's pairs move by more than d_min from
    # frame to frame (measured: 68 % of them within d_min of a history pair at 16-18 m and 37 % at
    # 18-20 m, against 94 % at 6-14 m) and Eq. 16's misses prune them before the three hits that
    # confirm them. The HDL-64's far pairs gained no recall from it, only false obstacles on rough
    # ground (docs/detector_features.md). inf = the paper's fixed d_min.
    match_full_range_m: float = 10.0
    max_match_scale: float = 2.0
    range_scaled_sensors: tuple[str, ...] = ("hdl32_left", "hdl32_right")  # paper N's side HDL-32s
    prior: float = 0.5  # prior of a newly seen pair
    confirm_posterior: float = 0.95  # confirmed at >= this (3 hits, §4.2)
    prune_posterior: float = 0.1  # dropped below this
    max_pairs: int = 20000  # history bound
    max_age_frames: int = 50  # history bound
    likelihoods: Mapping[str, SensorLikelihood] | None = None  # per sensor; None -> default
    # A history pair hit within d_min moves its A along its A->B line to where the hitting pair's
    # A projects, when that is between A and B. Not in paper N, whose history keeps a pair's first
    # geometry: A is the last ground return before the gap, up to a ring gap short of the rim (1.1
    # m at 15 m), so a pit confirmed far out kept that early edge while the car came close, and
    # the grid marked the ground before the rim as obstacle.
    tighten_on_match: bool = False

    def __post_init__(self) -> None:
        require(
            np.isfinite(self.match_distance_m) and self.match_distance_m > 0,
            "match_distance_m",
            "must be finite and > 0",
        )
        require(self.match_full_range_m > 0, "match_full_range_m", "must be > 0 (inf: a fixed d_min)")
        require(
            np.isfinite(self.max_match_scale) and self.max_match_scale >= 1,
            "max_match_scale",
            "must be finite and >= 1",
        )
        require(0.0 < self.prior < 1.0, "prior", "must be in (0, 1)")
        require(0.0 < self.confirm_posterior < 1.0, "confirm_posterior", "must be in (0, 1)")
        require(0.0 <= self.prune_posterior < self.prior, "prune_posterior", "must be in [0, prior)")
        require(
            isinstance(self.range_scaled_sensors, tuple)
            and all(isinstance(n, str) for n in self.range_scaled_sensors),
            "range_scaled_sensors",
            "must be a tuple of sensor names",
        )
        require(self.max_pairs > 0, "max_pairs", "must be > 0")
        require(self.max_age_frames > 0, "max_age_frames", "must be > 0")

    def likelihood(self, sensor: str) -> SensorLikelihood:
        """Likelihood of ``sensor`` (default when not configured)."""
        if self.likelihoods is not None and sensor in self.likelihoods:
            return self.likelihoods[sensor]
        return SensorLikelihood()


def bayes_hit(p: np.ndarray, lik: SensorLikelihood) -> np.ndarray:
    """Eq. 15: posterior after a detection."""
    num = lik.p_hit_given_obstacle * p
    return num / (num + lik.p_hit_given_free * (1.0 - p))


def bayes_miss(p: np.ndarray, lik: SensorLikelihood) -> np.ndarray:
    """Eq. 16: posterior after no sensor detected the pair."""
    num = (1.0 - lik.p_hit_given_obstacle) * p
    return num / (num + (1.0 - lik.p_hit_given_free) * (1.0 - p))


@dataclass(frozen=True)
class FusedPairs:
    """Fused pairs in the current vehicle frame with their posteriors."""

    a_m: np.ndarray
    b_m: np.ndarray
    posterior: np.ndarray
    confirmed: np.ndarray

    def __len__(self) -> int:
        return int(self.a_m.shape[0])


class PairFusion:
    """Keeps the pair history in the world frame and applies Eq. 15/16 each frame."""

    def __init__(self, config: FusionConfig | None = None) -> None:
        if config is not None and not isinstance(config, FusionConfig):
            raise ConfigError("config", "must be a FusionConfig")
        self.config = config or FusionConfig()
        self.reset()

    def reset(self) -> None:
        """Forget the history."""
        self._a_w = np.empty((0, 3))
        self._b_w = np.empty((0, 3))
        self._p = np.empty(0)
        self._age = np.empty(0, dtype=np.int64)

    def __len__(self) -> int:
        return int(self._p.shape[0])

    def update(
        self,
        pairs: Mapping[str, FeaturePairs],
        pose: Pose,
        coverage_xy_m: tuple[float, float, float, float] | None = None,
    ) -> FusedPairs:
        """Fuse this frame's pairs (vehicle frame) at INS ``pose``.

        ``coverage_xy_m``: the vehicle-frame box ``(x_min, x_max, y_min, y_max)`` the frame's
        scans covered, for a partial frame (None: the whole ground). Only history pairs with A and
        B inside it take Eq. 16's miss update: where no sensor looked, not detecting a pair is no
        evidence against it (the paper's frames are whole; documented deviation for partial ones).

        Raises:
            ScanError: ``pose`` has a non-finite value, or a pair has a non-finite A/B.
        """
        if not np.all(np.isfinite(pose.as_array())):
            raise ScanError("pose: contains NaN/inf")
        cfg = self.config
        n_hist = len(self)
        a_v = pose.to_vehicle(self._a_w) if n_hist else np.empty((0, 3))
        b_v = pose.to_vehicle(self._b_w) if n_hist else np.empty((0, 3))
        p = self._p.copy()
        age = self._age + 1
        matched_any = np.zeros(n_hist, dtype=bool)
        frame = [(sensor, fp) for sensor, fp in pairs.items() if len(fp)]
        for sensor, fp in frame:
            if not (np.all(np.isfinite(fp.a_m)) and np.all(np.isfinite(fp.b_m))):
                raise ScanError(f"pairs[{sensor!r}]: A/B contain NaN/inf")
        reach = [self._reach(sensor, fp) for sensor, fp in frame]
        # every frame pair against the history this frame started with, in one search
        found = _search(a_v, b_v, [fp for _, fp in frame], reach)
        start = 0
        for (sensor, fp), reach_fp in zip(frame, reach, strict=True):
            lik = cfg.likelihood(sensor)
            stop = start + len(fp)
            at = (found[1] >= start) & (found[1] < stop)
            i, j, d = found[0][at], found[1][at] - start, found[2][at]
            start = stop
            if len(p) > n_hist:
                # pairs created earlier in this frame by another sensor are matched too, so three
                # sensors seeing a new pair in one frame confirm it at once (paper N §4.2)
                i_new, j_new, d_new = _search(a_v[n_hist:], b_v[n_hist:], [fp], [reach_fp])
                i, j, d = (
                    np.concatenate([i, i_new + n_hist]),
                    np.concatenate([j, j_new]),
                    np.concatenate([d, d_new]),
                )
            if cfg.tighten_on_match:
                _tighten(a_v, b_v, i, fp.a_m[j], d <= cfg.match_distance_m)
            hit = np.zeros(len(p), dtype=bool)
            hit[i] = True
            p[hit] = bayes_hit(p[hit], lik)
            matched_any |= hit
            age[hit] = 0
            # a frame pair is new unless it lies within d_min itself of a history pair: one matched
            # only by the range-scaled reach is a hit for that pair and enters the history too
            fresh = np.ones(len(fp), dtype=bool)
            fresh[j[d <= cfg.match_distance_m]] = False
            n_new = int(fresh.sum())
            a_v = np.concatenate([a_v, fp.a_m[fresh]])
            b_v = np.concatenate([b_v, fp.b_m[fresh]])
            p = np.concatenate([p, bayes_hit(np.full(n_new, cfg.prior), lik)])
            age = np.concatenate([age, np.zeros(n_new, dtype=np.int64)])
            matched_any = np.concatenate([matched_any, np.ones(n_new, dtype=bool)])
        miss = ~matched_any
        if coverage_xy_m is not None:
            miss &= in_box(a_v, coverage_xy_m) & in_box(b_v, coverage_xy_m)
        if np.any(miss):
            p[miss] = bayes_miss(p[miss], cfg.likelihood("default"))
        a_all, b_all, p_all, age_all = a_v, b_v, p, age
        keep = (p_all >= cfg.prune_posterior) & (age_all <= cfg.max_age_frames)
        a_all, b_all, p_all, age_all = a_all[keep], b_all[keep], p_all[keep], age_all[keep]
        if p_all.shape[0] > cfg.max_pairs:
            order = np.argsort(-p_all, kind="stable")[: cfg.max_pairs]
            a_all, b_all, p_all, age_all = a_all[order], b_all[order], p_all[order], age_all[order]
        self._a_w = pose.to_world(a_all) if len(a_all) else np.empty((0, 3))
        self._b_w = pose.to_world(b_all) if len(b_all) else np.empty((0, 3))
        self._p, self._age = p_all, age_all
        return FusedPairs(a_all, b_all, p_all, p_all >= cfg.confirm_posterior)

    def _reach(self, sensor: str, fp: FeaturePairs) -> np.ndarray:
        """Per frame pair: how close a history pair must be to be hit by it (d_min, range-scaled for
        the ``range_scaled_sensors``)."""
        cfg = self.config
        reach = np.full(len(fp), cfg.match_distance_m)
        if sensor in cfg.range_scaled_sensors:
            reach *= range_scale(fp.a_m, fp.b_m, cfg.match_full_range_m, cfg.max_match_scale)
        return reach


def in_box(points_m: np.ndarray, box_xy_m: tuple[float, float, float, float]) -> np.ndarray:
    """(N,) bool: the points' xy inside the closed box ``(x_min, x_max, y_min, y_max)``."""
    x0, x1, y0, y1 = box_xy_m
    x, y = points_m[:, 0], points_m[:, 1]
    return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)


def _tighten(a_v: np.ndarray, b_v: np.ndarray, i: np.ndarray, a_f: np.ndarray, close: np.ndarray) -> None:
    """In place: where ``close[k]``, move history pair ``i[k]``'s A along its own A->B line up to
    where frame pair ``k``'s A projects on it, when that lies between A and B (ground was seen
    there, so the gap starts later); of several, the farthest. B and the line stay."""
    e = b_v[i, :2] - a_v[i, :2]
    t = np.sum((a_f[:, :2] - a_v[i, :2]) * e, axis=1) / np.maximum(np.sum(e * e, axis=1), 1e-12)
    k = np.flatnonzero(close & (t > 0.0) & (t < 1.0))
    if k.size == 0:
        return
    k = k[np.lexsort((-t[k], i[k]))]  # by history pair, farthest first
    k = k[np.r_[True, i[k][1:] != i[k][:-1]]]
    rows = i[k]
    a_v[rows] += t[k, None] * (b_v[rows] - a_v[rows])


def _search(
    a_m: np.ndarray, b_m: np.ndarray, frame: list[FeaturePairs], reach: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i, j, distance) of history pair i (``a_m``, ``b_m``) and pair j of the concatenated ``frame``
    pairs within that frame pair's ``reach``, in the ground plane."""
    if len(a_m) == 0 or not frame:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty, np.empty(0)
    a_f = np.concatenate([fp.a_m[:, :2] for fp in frame])
    b_f = np.concatenate([fp.b_m[:, :2] for fp in frame])
    return close_pairs(a_m[:, :2], b_m[:, :2], a_f, b_f, np.concatenate(reach))
