"""Per-sensor feature-extraction configs of paper N §3.1/§3.2 (defaults = the paper's values)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from negobs_gym.errors import require


def _finite(value: float) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


@dataclass(frozen=True, kw_only=True)
class PairTestConfig:
    """Eq. 14 thresholds of the feature-pair test."""

    w_min_m: float = 0.30  # Eq. 14, minimum negative-obstacle width (paper N: 30 cm)
    gamma1: float = 1.5  # Eq. 14, d_AB >= gamma1 * d_BC (1.5 for HDL-64, 5 for HDL-32)
    gamma2: float = 0.15  # Eq. 14, dz_BC >= gamma2 * h * d_AB / y_A (0.15 HDL-64, 0.4 HDL-32)

    def __post_init__(self) -> None:
        require(_finite(self.w_min_m) and self.w_min_m > 0, "w_min_m", "must be finite and > 0")
        require(_finite(self.gamma1) and self.gamma1 >= 0, "gamma1", "must be finite and >= 0")
        require(_finite(self.gamma2) and self.gamma2 >= 0, "gamma2", "must be finite and >= 0")


@dataclass(frozen=True, kw_only=True)
class Hdl64FeatureConfig:
    """Top HDL-64 feature pairs: amplitude-direction convexity + back-wall density (paper N §3.1).

    Attributes beyond the paper (documented choices): ``side_window`` (points left/right of a bump
    averaged for the mean-range test; the paper says "a certain range"), the density search window
    (``density_laser_window`` lasers up and down, ``density_column_window`` columns either side)
    and ``sensor_height_m`` (None = the scan's mounting height ``translation_m[2]``).
    """

    max_filter_radius: int = 3  # §3.1 step 2, max filter of radius 3
    density_factor: float = 0.55  # Eq. 10, T_d64 = 0.55 * max(dr_n, dr_n+1)
    edge_rise_m: float = 0.20  # §3.1 step 4, T+ = 20 cm
    edge_fall_m: float = -0.20  # §3.1 step 4, T- = -20 cm
    edge_half_window: int = 2  # §3.1 step 4, 5-neighbourhood = i-2..i+2
    density_threshold: float = 1.75  # §3.1 step 4, D_th64
    side_window: int = 5
    density_laser_window: int = 6
    density_column_window: int = 2
    epsilon_deg: float = 0.09  # §3.1 step 5, Tab. 2 azimuth tolerance
    sensor_height_m: float | None = None
    pair_test: PairTestConfig = PairTestConfig()  # Eq. 14: 0.30 m, 1.5, 0.15

    def __post_init__(self) -> None:
        for name in ("max_filter_radius", "edge_half_window", "side_window"):
            v = getattr(self, name)
            require(isinstance(v, int) and v >= 1, name, "must be an integer >= 1")
        for name in ("density_laser_window", "density_column_window"):
            v = getattr(self, name)
            require(isinstance(v, int) and v >= 0, name, "must be an integer >= 0")
        require(_finite(self.density_factor) and self.density_factor > 0, "density_factor", "must be > 0")
        require(_finite(self.edge_rise_m) and self.edge_rise_m > 0, "edge_rise_m", "must be > 0")
        require(_finite(self.edge_fall_m) and self.edge_fall_m < 0, "edge_fall_m", "must be < 0")
        require(_finite(self.density_threshold), "density_threshold", "must be finite")
        require(_finite(self.epsilon_deg) and self.epsilon_deg >= 0, "epsilon_deg", "must be >= 0")
        require(
            self.sensor_height_m is None or (_finite(self.sensor_height_m) and self.sensor_height_m > 0),
            "sensor_height_m",
            "must be None or finite and > 0",
        )
        require(isinstance(self.pair_test, PairTestConfig), "pair_test", "must be a PairTestConfig")


@dataclass(frozen=True, kw_only=True)
class Hdl32FeatureConfig:
    """Side HDL-32 feature pairs: radial range jump + back-wall density (paper N §3.2).

    ``compensate_missing`` switches the missing-return compensation of §3.2 step 2;
    ``sensor_height_m`` None = the scan's mounting height ``translation_m[2]``.
    """

    density_radius_m: float = 0.15  # §3.2 step 3, T_d32 = 0.15 m
    density_half_window: int = 8  # columns either side searched for same-laser neighbours
    jump_threshold_m: float = 0.30  # §3.2 step 4, T32 = 0.30 m
    density_threshold: float = 4.0  # §3.2 step 4, D_th32 = 4
    # Beyond this horizontal range from the sensor the threshold falls as (range / this)^-2
    # (documented deviation): the back-wall returns a point can have within T_d32 are the visible
    # wall height h w / d (Eq. 7) over the firing step d * dalpha on it, ~ h w / (d^2 dalpha);
    # for a 1 m pit seen from 2 m they drop to 4 at ~12 m, so the paper's fixed D_th32 ends the
    # side sensors' reach there, against paper N Fig. 16. inf = the paper's fixed threshold.
    density_full_range_m: float = 12.0
    # the threshold never falls below this: B keeps at least one same-laser neighbour within
    # T_d32 (an isolated noise return has none)
    density_threshold_min: float = 1.5
    compensate_missing: bool = True
    # C = first point after B on the same laser at least this far from B (documented deviation:
    # the paper's literal "next point" is 0.0; at the HDL-32E's 0.16 deg firing step the next
    # point lies ~3 cm up the same back wall and can never meet Eq. 14's dz_BC test)
    c_min_separation_m: float = 0.15
    sensor_height_m: float | None = None
    pair_test: PairTestConfig = PairTestConfig(gamma1=5.0, gamma2=0.4)  # §3.2 step 5

    def __post_init__(self) -> None:
        require(
            _finite(self.density_radius_m) and self.density_radius_m > 0,
            "density_radius_m",
            "must be finite and > 0",
        )
        require(
            isinstance(self.density_half_window, int) and self.density_half_window >= 1,
            "density_half_window",
            "must be an integer >= 1",
        )
        require(
            _finite(self.jump_threshold_m) and self.jump_threshold_m > 0,
            "jump_threshold_m",
            "must be finite and > 0",
        )
        require(_finite(self.density_threshold), "density_threshold", "must be finite")
        require(
            isinstance(self.density_full_range_m, (int, float)) and self.density_full_range_m > 0,
            "density_full_range_m",
            "must be > 0 (inf for the paper's fixed threshold)",
        )
        require(
            _finite(self.density_threshold_min) and self.density_threshold_min <= self.density_threshold,
            "density_threshold_min",
            "must be finite and <= density_threshold",
        )
        require(
            _finite(self.c_min_separation_m) and self.c_min_separation_m >= 0,
            "c_min_separation_m",
            "must be finite and >= 0",
        )
        require(
            self.sensor_height_m is None or (_finite(self.sensor_height_m) and self.sensor_height_m > 0),
            "sensor_height_m",
            "must be None or finite and > 0",
        )
        require(isinstance(self.pair_test, PairTestConfig), "pair_test", "must be a PairTestConfig")


@dataclass(frozen=True, kw_only=True)
class GroundCheckConfig:
    """Checks of the HDL-64's feature pairs against the frame's ground (not in paper N).

    Paper N's Eq. 14 takes any range gap on the HDL-64's rings that ends on rising returns for a
    pit. On rough ground most are shadows: the ring's last return A on a bump's crest, the gap the
    ground hidden behind it, B on the hollow's far slope (docs/detector_features.md, "False
    alarms"). A pit's rim is level with the ground before it, its back wall is hit well below the
    rim and tops out at it. ``off()`` gives paper N's detector.
    """

    # shadow test: A stands more than this above the median lowest return of the crest_window_m of
    # its ground-map sector before it: A is a crest and the gap its shadow. On the campaign's
    # courses the rim of a true pit is within 3 cm of that ground for 95 % of the pairs (and 55 %
    # of the false alarms' pairs stand higher)
    crest_rise_m: float = 0.03
    crest_window_m: float = 1.0
    # far side: C (the return past B on the back wall) lies more than this above A: the far side
    # climbs above the near rim (a hollow's far slope, a rise), where a pit's back wall tops out at
    # the rim's level (96 % of true pairs within 5 cm)
    far_rise_m: float = 0.05
    # depth evidence: B lies below A by at least this share of the ray's drop across the gap,
    # d_AB * h / y_A (Eq. 14's own scale). A pit's back wall is hit below the rim (median share
    # 0.66 on the campaign's true pairs); a shadow's far ground is often level with the crest
    min_depth_ratio: float = 0.3

    def __post_init__(self) -> None:
        for name in ("crest_rise_m", "far_rise_m"):
            v = getattr(self, name)
            require(
                isinstance(v, (int, float)) and not math.isnan(v) and v >= 0, name, "must be >= 0 (inf: off)"
            )
        require(
            _finite(self.crest_window_m) and self.crest_window_m > 0,
            "crest_window_m",
            "must be finite and > 0",
        )
        require(
            _finite(self.min_depth_ratio) and self.min_depth_ratio >= 0,
            "min_depth_ratio",
            "must be finite and >= 0 (0: off)",
        )

    @classmethod
    def off(cls) -> GroundCheckConfig:
        """No check: paper N's Eq. 14 alone."""
        return cls(crest_rise_m=math.inf, far_rise_m=math.inf, min_depth_ratio=0.0)
