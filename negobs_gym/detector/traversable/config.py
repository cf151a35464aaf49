"""Configuration of paper T's traversable-region detector (4-layer IBEO LUX).

Paper T gives the structure of every step but few numbers: the layer elevations (Eq. 3), the mount
(0.65 m, pitched down 5.03 degrees), the maximum steering angle (35 degrees) and the algorithm's
choice of layers. Every other threshold below is our own choice for that mount, marked "not in
paper T" with the reason, so it can be tuned against recorded data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from negobs_gym.errors import require


@dataclass(frozen=True, kw_only=True)
class TraversableConfig:
    """Thresholds and vehicle constants of the traversable-region detector (SI units).

    Laser indices follow the detector order of :class:`~negobs_gym.core.StructuredScan`: index 0
    is the lowest elevation (-1.2 deg, nearest ground hit), index 3 the highest (paper T's layer 1).
    """

    n_layers: int = 4  # paper T Eq. 3: the LUX has 4 layers
    # §4: the LUX reaches 200 m; a longer range is not a LUX return and is treated as none (it
    # would also blow up the Hough accumulator, whose rho axis spans the points' extent).
    max_range_m: float = 200.0
    # §3.1: the top layer is unreliable on rough ground; boundaries use the lower three layers.
    boundary_layers: tuple[int, ...] = (0, 1, 2)
    # §3.3 / Fig. 5: obstacles are searched on the middle two layers.
    obstacle_layers: tuple[int, ...] = (1, 2)

    # --- §3.1 tear points (Hough line + adjacent-distance threshold) ---
    # Not in paper T: Hough normal angles within +-30 deg of vehicle +Y (scan lines on the road
    # are "approximately parallel to the X axis", §3), 1 deg and 0.2 m bins.
    hough_max_tilt_deg: float = 30.0
    hough_angle_step_deg: float = 1.0
    hough_rho_step_m: float = 0.20
    # Not in paper T: every 2nd column votes (the least-squares refit then uses every point).
    hough_column_stride: int = 2
    # Not in paper T: a point within 0.6 m (across the line) of its layer's scan line lies on
    # it. At this mount a ground hit moves ~10 m along the ray per metre of height, so 0.6 m
    # keeps ruts and a ~8 cm road crown (Fig. 10) on the line and drops bank points higher than
    # ~6 cm.
    line_tolerance_m: float = 0.60
    # Not in paper T (it keeps the Hough line): each layer is refit as a parabola in its Hough
    # line's frame, since a pitched-down LUX draws conics (over 110 deg the ends bend 0.4-0.5 m off
    # a straight line on flat ground). Two refits (the first drops the Hough band's outliers);
    # a layer with fewer than 6 inliers keeps its Hough band.
    curve_refits: int = 2
    curve_min_points: int = 6
    # Not in paper T: adjacent on-line points farther apart than this are a tear (0.25 deg
    # columns are < 0.1 m apart on the road within 12 m; 0.5 m tolerates a few dropouts).
    tear_distance_m: float = 0.50
    # Not in paper T ("n consecutive points without a tear"): 5.
    clean_run_points: int = 5
    # Not in paper T: a segment end whose next return outwards is 0.5 m nearer is an occlusion
    # edge (an obstacle hides the road edge, Fig. 12), not a boundary point.
    occlusion_jump_m: float = 0.5

    # --- §3.2 Kalman filter per boundary-point coordinate (F = H = I, u = 0) ---
    # Not in paper T (R "from repeated scans of one object", Q "empirical"): R = (0.3 m)^2 for
    # the bounce-driven jitter of a LUX boundary point, Q = (0.1 m)^2 per frame.
    kalman_measurement_var_m2: float = 0.09
    kalman_process_var_m2: float = 0.01
    # Not in paper T: a layer's boundary point more than 1 m (x) from the median of its side's
    # layers is dropped for the frame (a bend leans the layers' ends < 0.7 m apart).
    layer_consistency_m: float = 1.0
    # Not in paper T: a boundary point whose x jumps more than 1 m from the estimate is held back
    # (bumps or an occluder cut a segment short); 3 such frames in a row restart the filter.
    kalman_gate_x_m: float = 1.0
    kalman_gate_reset_frames: int = 3
    # Not in paper T (F = I holds the estimates still in the vehicle frame, right while driving
    # straight): before each predict, move each estimate along its side's last boundary line,
    # moved by the pose change between frames (planar: yaw and x, y), to its layer's distance; a
    # boundary point a layer stops seeing in a bend then turns with the road, not with the car.
    kalman_ego_motion: bool = False
    # Not in paper T: a line turned more than 60 deg off the car's axis after the move is no lateral
    # boundary to carry points along; its side's estimates restart from the next measurement.
    kalman_carry_max_angle_deg: float = 60.0
    # Not in paper T: the car drives between the boundaries (A1: they meet the LiDAR's X axis on
    # either side of it), so a carried line that passes the LiDAR less than this far out on its own
    # side (a wrong slope carried frame after frame) is no boundary; its side's estimates restart.
    # None: no check.
    kalman_carry_min_clearance_m: float | None = 0.0

    # --- §3.3 obstacle clustering ---
    # Not in paper T: d_T1 = 0.2 m. On an upright face adjacent layers are 0.8 deg apart (< 0.14 m
    # within the 9.7 m the top layer reaches on the ground); on flat ground > 0.9 m (d_o << d_g).
    # 0.2 m also rejects bump faces facing the sensor up to ~20 deg of slope.
    d_t1_m: float = 0.20
    # Not in paper T: neighbours on the adjacent layer are searched within +-2 columns.
    neighbour_columns: int = 2
    # Not in paper T: d_T2 = 1.5 m, about a car's half length (greedy centroid clustering).
    d_t2_m: float = 1.5
    # Not in paper T: a cluster needs 3 points (a pedestrian needs enough returns, §4).
    min_cluster_points: int = 3
    # Not in paper T: obstacle points must lie this far inside the boundary lines, so earth banks
    # (which also have closely stacked layers) are borders, not obstacles.
    obstacle_inside_margin_m: float = 0.30
    # Not in paper T (its obstacles are per frame): keep each frame's obstacle points this long
    # [s] in the world frame (INS pose) and mark them in ``positive_obstacles`` while the LUX no
    # longer sees them (a rock within ~2 m of the LUX passes under its layers). 0 = per frame, as
    # the paper.
    obstacle_hold_s: float = 0.0

    # --- §3.5 reachability ---
    vehicle_width_m: float = 2.0  # docs/physics.md: d_c, a 4.5 x 2.0 m vehicle
    # Not in paper T: safety margin epsilon of Eq. 12.
    safety_margin_m: float = 0.30
    wheelbase_m: float = 2.8  # Eq. 13: l, docs/physics.md
    max_steering_deg: float = 35.0  # §3.5: phi_max = 35 deg
    # Not in paper T: sampled path family (turn, or turn + counter-turn, then straight), 21
    # curvatures x 12 arc lengths each, sampled every 0.2 m up to 30 m.
    reach_curvatures: int = 21
    reach_switch_points: int = 12
    reach_step_m: float = 0.20
    reach_length_m: float = 30.0

    def __post_init__(self) -> None:
        require(self.n_layers >= 3, "n_layers", f"must be >= 3, got {self.n_layers}")
        for name in ("boundary_layers", "obstacle_layers"):
            layers = getattr(self, name)
            require(
                len(layers) > 0 and all(isinstance(i, int) and 0 <= i < self.n_layers for i in layers),
                name,
                f"must be non-empty laser indices in [0, {self.n_layers}), got {layers}",
            )
        require(
            all(0 < i < self.n_layers - 1 for i in self.obstacle_layers),
            "obstacle_layers",
            "must have a laser on each side (not the first or last index)",
        )
        positive = (
            "max_range_m",
            "hough_angle_step_deg",
            "hough_rho_step_m",
            "line_tolerance_m",
            "tear_distance_m",
            "occlusion_jump_m",
            "kalman_measurement_var_m2",
            "kalman_process_var_m2",
            "kalman_gate_x_m",
            "layer_consistency_m",
            "d_t1_m",
            "d_t2_m",
            "vehicle_width_m",
            "wheelbase_m",
            "reach_step_m",
            "reach_length_m",
        )
        for name in positive:
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value}")
        for name in ("safety_margin_m", "obstacle_inside_margin_m", "obstacle_hold_s"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, name, f"must be finite and >= 0, got {value}")
        require(
            math.isfinite(self.hough_max_tilt_deg) and 0 <= self.hough_max_tilt_deg < 90,
            "hough_max_tilt_deg",
            f"must be in [0, 90), got {self.hough_max_tilt_deg}",
        )
        require(
            math.isfinite(self.kalman_carry_max_angle_deg) and 0 < self.kalman_carry_max_angle_deg < 90,
            "kalman_carry_max_angle_deg",
            f"must be in (0, 90), got {self.kalman_carry_max_angle_deg}",
        )
        clearance = self.kalman_carry_min_clearance_m
        require(
            clearance is None
            or (
                isinstance(clearance, (int, float))
                and not isinstance(clearance, bool)
                and math.isfinite(clearance)
            ),
            "kalman_carry_min_clearance_m",
            f"must be a finite number [m] or None (no check), got {clearance!r}",
        )
        require(
            math.isfinite(self.max_steering_deg) and 0 < self.max_steering_deg < 90,
            "max_steering_deg",
            f"must be in (0, 90), got {self.max_steering_deg}",
        )
        for name in (
            "clean_run_points",
            "min_cluster_points",
            "kalman_gate_reset_frames",
            "hough_column_stride",
            "reach_curvatures",
            "reach_switch_points",
        ):
            value = getattr(self, name)
            require(isinstance(value, int) and value >= 1, name, f"must be an int >= 1, got {value}")
        require(
            isinstance(self.kalman_ego_motion, bool),
            "kalman_ego_motion",
            f"must be a bool, got {self.kalman_ego_motion!r}",
        )
        require(
            isinstance(self.curve_refits, int) and self.curve_refits >= 0,
            "curve_refits",
            f"must be an int >= 0 (0 keeps the Hough line), got {self.curve_refits}",
        )
        require(
            isinstance(self.curve_min_points, int) and self.curve_min_points >= 3,
            "curve_min_points",
            f"must be an int >= 3 (a parabola has 3 coefficients), got {self.curve_min_points}",
        )
        require(
            isinstance(self.neighbour_columns, int) and self.neighbour_columns >= 0,
            "neighbour_columns",
            f"must be an int >= 0, got {self.neighbour_columns}",
        )

    @property
    def max_steering_rad(self) -> float:
        """phi_max [rad]."""
        return math.radians(self.max_steering_deg)

    @property
    def rear_turn_radius_m(self) -> float:
        """rho_r = l / tan(phi_max), the rear-axle turning radius (Eq. 13) [m]."""
        return self.wheelbase_m / math.tan(self.max_steering_rad)

    @property
    def front_turn_radius_m(self) -> float:
        """rho_f = l / sin(phi_max), the front-axle turning radius (Eq. 13) [m]."""
        return self.wheelbase_m / math.sin(self.max_steering_rad)
