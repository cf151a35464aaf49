"""Check a ray-cast backend against the reference: hit/miss and range agreement, and a test scene.

Used by the agreement tests and ``negobs bench detector``'s ``raycast_agreement`` figure
(docs/sensors.md: the fast backend agrees with PyBullet to 1 cm on the same scene).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from negobs_gym.errors import ScanError, require
from negobs_gym.sim.types import Terrain


@dataclass(frozen=True)
class Agreement:
    """How far two backends' ranges for the same rays agree.

    Attributes:
        n_rays: Rays compared.
        hit_miss: Share of rays that both hit or both miss.
        n_common_hits: Rays both hit.
        within_tol: Share of common hits with ``|r_a - r_b| <= tol_m``.
        max_abs_dr_m: Largest range difference over common hits [m] (0 when there are none).
        tol_m: The range tolerance used [m].
        overall: Share of all rays that agree: same hit/miss and, for hits, within ``tol_m``.
    """

    n_rays: int
    hit_miss: float
    n_common_hits: int
    within_tol: float
    max_abs_dr_m: float
    tol_m: float
    overall: float


def compare_ranges(reference_m: np.ndarray, candidate_m: np.ndarray, tol_m: float = 0.01) -> Agreement:
    """Compare two range arrays of the same rays (NaN = miss); ``tol_m`` default is docs/sensors.md's 1 cm.

    Raises:
        ScanError: Shapes differ or there are no rays.
    """
    require(math.isfinite(tol_m) and tol_m >= 0, "tol_m", f"must be finite and >= 0, got {tol_m}")
    a = np.asarray(reference_m, dtype=np.float64).ravel()
    b = np.asarray(candidate_m, dtype=np.float64).ravel()
    if np.shape(reference_m) != np.shape(candidate_m):
        raise ScanError(f"range arrays differ in shape: {np.shape(reference_m)} vs {np.shape(candidate_m)}")
    if a.size == 0:
        raise ScanError("no rays to compare")
    ha, hb = np.isfinite(a), np.isfinite(b)
    both = ha & hb
    dr = np.abs(a[both] - b[both])
    ok = dr <= tol_m
    agree = (ha == hb) & ~ha  # both miss
    agree[both] = ok
    return Agreement(
        n_rays=int(a.size),
        hit_miss=float(np.mean(ha == hb)),
        n_common_hits=int(both.sum()),
        within_tol=float(ok.mean()) if dr.size else 1.0,
        max_abs_dr_m=float(dr.max()) if dr.size else 0.0,
        tol_m=float(tol_m),
        overall=float(agree.mean()),
    )


def agreement_terrain(seed: int = 0, *, resolution_m: float = 0.10, length_m: float = 60.0) -> Terrain:
    """Rough straight course with a pit, a trench and positive obstacles (box rock, cylinder
    pedestrian, parked car): the scene the backends are compared on (issue 3 acceptance)."""
    from negobs_gym.sim.carving import NegativeObstacleSpec, PositiveObstacleSpec
    from negobs_gym.sim.terrain import TerrainConfig, generate_terrain

    require(length_m >= 50.0, "length_m", f"must be >= 50 m to hold the obstacles, got {length_m}")
    config = TerrainConfig(
        resolution_m=resolution_m,
        length_m=length_m,
        negative_obstacles=(
            NegativeObstacleSpec(kind="pit", length_m=1.0, width_m=1.0, depth_m=0.8, station_m=12.0),
            NegativeObstacleSpec(kind="trench", length_m=3.0, width_m=10.0, depth_m=1.0, station_m=34.0),
        ),
        positive_obstacles=(
            PositiveObstacleSpec(kind="rock", station_m=18.0, lateral_m=2.0, yaw_deg=20.0),
            PositiveObstacleSpec(kind="pedestrian", station_m=22.0, lateral_m=-2.5),
            PositiveObstacleSpec(kind="vehicle", station_m=44.0, lateral_m=-1.5, yaw_deg=180.0),
            PositiveObstacleSpec(kind="mound", station_m=27.0, lateral_m=6.0),
        ),
    )
    return generate_terrain(config, seed)
