"""Checks of feature pairs against the frame's ground (:class:`.config.GroundCheckConfig`).

Three tests on each (A, B, C) that passed Eq. 14, none in paper N:

- shadow (crest) test: A higher than the lowest returns of the ground-map cells just before it on
  its sector (all sensors of the frame): A is a crest, the gap behind it its shadow;
- far side: C higher than A, the far side climbs above the near rim;
- depth evidence: B not below A by a share of the ray's drop across the gap.
"""

from __future__ import annotations

import math

import numpy as np

from negobs_gym.detector.config import GroundCheckConfig
from negobs_gym.detector.pairs import FeaturePairs
from negobs_gym.detector.roi import GroundMap


def crest_rise_m(a_m: np.ndarray, ground: GroundMap, window_m: float) -> np.ndarray:
    """(n,) how far each A stands above the median lowest return of the ``window_m`` of its
    ground-map sector before it (NaN where none of those cells holds a return)."""
    a = np.asarray(a_m, dtype=np.float64).reshape(-1, 3)
    if len(a) == 0 or ground.lowest_z_m is None:
        return np.full(len(a), np.nan)
    sector, b, _ = ground.cells(a[:, :2])
    k = max(1, math.ceil(window_m / ground.config.bin_m))
    bins = b[:, None] - np.arange(1, k + 1)[None, :]
    z = ground.lowest_z_m[sector[:, None], np.clip(bins, 0, None)]
    z = np.where((bins >= 0) & np.isfinite(z), z, np.nan)
    with np.errstate(all="ignore"):
        seen = np.isfinite(z).any(axis=1)
        med = np.full(len(a), np.nan)
        if seen.any():
            med[seen] = np.nanmedian(z[seen], axis=1)
    return a[:, 2] - med


def ground_check(
    pairs: FeaturePairs,
    ground: GroundMap | None,
    sensor_m: np.ndarray,
    height_m: float,
    config: GroundCheckConfig,
) -> FeaturePairs:
    """The pairs that pass the checks of ``config`` (the crest test only with a ground map)."""
    if len(pairs) == 0:
        return pairs
    a, b, c = pairs.a_m, pairs.b_m, pairs.c_m
    keep = np.ones(len(pairs), dtype=bool)
    if math.isfinite(config.crest_rise_m) and ground is not None:
        rise = crest_rise_m(a, ground, config.crest_window_m)
        keep &= ~(rise > config.crest_rise_m)  # NaN (no ground seen before A): kept
    if math.isfinite(config.far_rise_m):
        keep &= ~(c[:, 2] - a[:, 2] > config.far_rise_m)
    if config.min_depth_ratio > 0:
        s = np.asarray(sensor_m, dtype=np.float64).reshape(-1, 3)
        d_ab = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])
        y_a = np.hypot(a[:, 0] - s[:, 0], a[:, 1] - s[:, 1])
        with np.errstate(all="ignore"):
            keep &= a[:, 2] - b[:, 2] >= config.min_depth_ratio * d_ab * height_m / y_a
    return FeaturePairs(pairs.sensor, a[keep], b[keep], c[keep])
