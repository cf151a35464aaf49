"""Acceptance tests of the paper T detector on analytic 4-layer scans."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from negobs_gym.core import GridSpec, Pose, StructuredScan
from negobs_gym.detector.traversable import (
    Box,
    LuxRig,
    TrackScene,
    TraversableConfig,
    TraversableRegionDetector,
    random_bumps,
    synthetic_scan,
)
from negobs_gym.errors import ScanError

CAR = Box(x_m=0.0, y_m=10.0 + 2.25, size_x_m=1.8, size_y_m=4.5, height_m=1.5)  # near face at 10 m


@pytest.fixture(scope="module")
def detector() -> TraversableRegionDetector:
    return TraversableRegionDetector()


def run(detector: TraversableRegionDetector, scan: StructuredScan):
    detector.reset()
    return detector.update(scan, Pose())


def grid_cell(detector: TraversableRegionDetector, x: float, y: float) -> tuple[int, int]:
    row, col, inside = detector.grid.cell_of(np.array([x, y]))
    assert inside
    return int(row), int(col)


@pytest.mark.parametrize("border", ["bank", "drop"])
@pytest.mark.parametrize(("left_w", "right_w"), [(4.0, 4.0), (3.0, 5.0)])
def test_straight_track_boundaries_within_20cm(detector, border, left_w, right_w) -> None:
    scene = TrackScene(left_half_width_m=left_w, right_half_width_m=right_w, border=border)
    res = run(detector, synthetic_scan(scene))
    ys = np.linspace(res.polygon_m[:, 1].min(), res.polygon_m[:, 1].max(), 20)
    assert np.abs(res.left_line.x_at(ys) - scene.left_edge_x(ys)).max() <= 0.2
    assert np.abs(res.right_line.x_at(ys) - scene.right_edge_x(ys)).max() <= 0.2
    assert res.obstacles == []
    # Region starts on the LiDAR's X axis (A1) and is traversable in the middle of the road.
    assert res.polygon_m[:, 1].min() == pytest.approx(LuxRig().forward_m)
    assert res.traversable[grid_cell(detector, 0.0, 8.0)]
    assert not res.traversable[grid_cell(detector, -left_w - 1.0, 8.0)]
    assert res.reachable[grid_cell(detector, 0.0, 8.0)]


@pytest.mark.parametrize("crown", [0.03, 0.06])
def test_road_crown_does_not_move_boundaries(detector, crown) -> None:
    # Paper T Fig. 10: road centre slightly higher than its sides; the sag of the scan lines must
    # not disturb the line detection.
    scene = TrackScene(crown_m=crown)
    res = run(detector, synthetic_scan(scene))
    ys = np.linspace(res.polygon_m[:, 1].min(), res.polygon_m[:, 1].max(), 20)
    assert np.abs(res.left_line.x_at(ys) - scene.left_edge_x(ys)).max() <= 0.2
    assert np.abs(res.right_line.x_at(ys) - scene.right_edge_x(ys)).max() <= 0.2
    assert res.obstacles == []


@pytest.mark.parametrize("ped_y", [9.5, 10.5, 12.0])
def test_pedestrian_beside_drop_off(detector, ped_y) -> None:
    # Paper T Fig. 14: drop-offs on both sides, a pedestrian near the right edge.
    ped = Box(x_m=3.0, y_m=ped_y, size_x_m=0.5, size_y_m=0.4, height_m=1.7)
    scene = TrackScene(border="drop", boxes=(ped,))
    res = run(detector, synthetic_scan(scene))
    assert len(res.obstacles) == 1
    assert abs(res.obstacles[0].centre_xy_m[0] - 3.0) < 0.3
    assert abs(res.left_line.x_at(10.0) + 4.0) < 0.2 and abs(res.right_line.x_at(10.0) - 4.0) < 0.3
    assert not res.traversable[grid_cell(detector, 3.0, ped_y + 1.0)]  # its shadow


def test_parked_motorbike_on_crowned_road(detector) -> None:
    # Paper T Fig. 13: a motorbike parked at the road side on uneven ground.
    bike = Box(x_m=-2.8, y_m=11.0, size_x_m=0.7, size_y_m=2.0, height_m=1.1)
    res = run(detector, synthetic_scan(TrackScene(crown_m=0.05, boxes=(bike,))))
    assert len(res.obstacles) == 1 and abs(res.obstacles[0].centre_xy_m[0] + 2.8) < 0.4
    assert res.traversable[grid_cell(detector, 1.0, 9.0)]
    assert not res.feasible[grid_cell(detector, -2.8, 11.0)]


@pytest.mark.parametrize("radius", [25.0, -25.0])
def test_bend_lines_lean_the_right_way(detector, radius) -> None:
    res = run(detector, synthetic_scan(TrackScene(bend_radius_m=radius)))
    sign = math.copysign(1.0, radius)
    assert sign * res.left_line.slope > 0.15
    assert sign * res.right_line.slope > 0.15


def test_scan_lines_leaving_the_field_of_view_give_no_boundary_points(detector) -> None:
    # The cause of the simulated straight track's tilted left line: ground rising to the left of
    # the vehicle (here the vehicle rolled right-side down relative to it) pulls the left scan
    # lines in until they end at the 55 deg edge of the FOV, still on the road. Those ends lie on
    # the FOV's edge ray, inside the road, and would tilt the left line along that ray.
    scene = TrackScene(left_half_width_m=4.5, right_half_width_m=4.5)
    res = run(detector, synthetic_scan(scene, vehicle_roll_rad=math.radians(-4.0)))
    assert np.isnan(res.raw_left_m).all()  # every left end is an FOV cut: unknown, not an edge
    assert res.left_line is None and not res.traversable.any()  # an unknown side bounds nothing
    assert np.abs(res.raw_right_m[:, 0] - 4.5).max() < 0.3
    # Rolled a little less, the far layer reaches the bank: the left line is the road edge.
    res = run(detector, synthetic_scan(scene, vehicle_roll_rad=math.radians(-3.5)))
    assert np.isfinite(res.raw_left_m).all(axis=1).sum() >= 1
    ys = np.linspace(res.polygon_m[:, 1].min(), res.polygon_m[:, 1].max(), 20)
    assert np.abs(res.left_line.x_at(ys) - scene.left_edge_x(ys)).max() <= 0.15


def test_car_at_10m_is_one_cluster_and_its_shadow_is_cut(detector) -> None:
    res = run(detector, synthetic_scan(TrackScene(boxes=(CAR,))))
    assert len(res.obstacles) == 1
    c = res.obstacles[0]
    assert abs(c.centre_xy_m[0]) < 0.3 and 9.8 < c.centre_xy_m[1] < 10.6
    assert 1.4 < c.width_m < 2.6
    assert len(res.shadow_polygons_m) == 1
    # Behind the car (its shadow) is cut; beside it and in front of it the road stays traversable.
    assert not res.traversable[grid_cell(detector, 0.0, 11.5)]
    assert not res.traversable[grid_cell(detector, 0.5, 10.3)]
    assert res.traversable[grid_cell(detector, 0.0, 8.0)]
    # Beside the car (its near face is at 10 m; the region ends at the farthest boundary point,
    # layer 2's road edge at ~11.1 m).
    assert res.traversable[grid_cell(detector, -3.0, 10.6)]
    assert res.traversable[grid_cell(detector, 3.0, 10.6)]
    assert res.positive_obstacles[grid_cell(detector, 0.0, 10.0)]
    # Boundaries are still the road edges (outer segment ends of the interrupted layers).
    assert abs(res.left_line.x_at(10.0) + 4.0) < 0.2 and abs(res.right_line.x_at(10.0) - 4.0) < 0.2
    # Reachability (Eq. 12): the vehicle cannot pass through the car.
    assert not res.reachable[grid_cell(detector, 0.0, 10.0)]


def test_two_separated_obstacles_are_two_clusters(detector) -> None:
    boxes = (
        Box(x_m=-2.2, y_m=10.5, size_x_m=0.6, size_y_m=0.6, height_m=1.7),
        Box(x_m=2.2, y_m=10.5, size_x_m=0.6, size_y_m=0.6, height_m=1.7),
    )
    res = run(detector, synthetic_scan(TrackScene(boxes=boxes)))
    xs = sorted(float(c.centre_xy_m[0]) for c in res.obstacles)
    assert len(xs) == 2 and xs[0] < -1.5 and xs[1] > 1.5


def test_kalman_halves_boundary_jitter_under_pitch_bouncing() -> None:
    rng = np.random.default_rng(7)
    scene = TrackScene(bend_radius_m=40.0)
    det = TraversableRegionDetector()
    raw, filt = [], []
    for _ in range(40):
        pitch = rng.normal(0.0, math.radians(0.4))
        scan = synthetic_scan(scene, vehicle_pitch_rad=pitch, range_noise_m=0.02, rng=rng)
        res = det.update(scan, Pose())
        raw.append(np.concatenate([res.raw_left_m, res.raw_right_m]))
        filt.append(np.concatenate([res.left_points_m, res.right_points_m]))
    raw_a, filt_a = np.array(raw)[10:], np.array(filt)[10:]  # after the filters settle
    assert np.isfinite(raw_a).all()
    raw_var = raw_a.var(axis=0).sum()
    filt_var = filt_a.var(axis=0).sum()
    assert raw_var > 0.05  # the bouncing really moves the boundary points
    assert filt_var / raw_var <= 0.5


def bumpy_scans() -> list[StructuredScan]:
    """25 frames driving 0.5 m/frame over rutted, bumpy ground while bouncing (the same frames for
    every config compared: casting them is ~95 % of a drive's cost)."""
    rng = np.random.default_rng(0)
    bumps = random_bumps(rng, amplitude_m=0.025, wavelength_m=1.5)  # ~5 cm peaks, like the sim's track
    rig = LuxRig(max_range_m=25.0)
    scans = []
    for i in range(25):
        scene = TrackScene(rut_depth_m=0.05, bumps=bumps, travelled_m=0.5 * i)
        pitch = rng.normal(0, math.radians(0.4))
        scans.append(synthetic_scan(scene, rig, vehicle_pitch_rad=pitch))
    return scans


def bumpy_drive(config: TraversableConfig, scans: list[StructuredScan]) -> tuple[np.ndarray, int]:
    """The detector with ``config`` over ``scans`` (:func:`bumpy_scans`); boundary errors."""
    det = TraversableRegionDetector(config)
    errors, false_obstacles = [], 0
    for scan in scans:
        res = det.update(scan, Pose())
        errors.append(max(abs(res.left_line.x_at(8.0) + 4.0), abs(res.right_line.x_at(8.0) - 4.0)))
        false_obstacles += len(res.obstacles)
    return np.array(errors[3:]), false_obstacles


def test_rough_ground_sequence_keeps_boundaries() -> None:
    # Ruts (5 cm) and 4.5 cm RMS bumps cut single layers short now and then; the cross-layer check
    # and the Kalman gate keep the lines on the road edges.
    scans = bumpy_scans()
    errors, false_obstacles = bumpy_drive(TraversableConfig(), scans)
    assert np.median(errors) < 0.15 and errors.max() < 0.5
    assert false_obstacles <= 2
    # Without the gate and the cross-layer check (the paper's bare filter) the lines wander off.
    bare, _ = bumpy_drive(TraversableConfig(kalman_gate_x_m=1e9, layer_consistency_m=1e9), scans)
    assert bare.max() > errors.max()


def test_deterministic_and_reset(detector) -> None:
    scan = synthetic_scan(TrackScene(boxes=(CAR,)), range_noise_m=0.02, rng=np.random.default_rng(3))
    a = run(detector, scan)
    b = run(detector, scan)
    assert np.array_equal(a.left_points_m, b.left_points_m)
    assert np.array_equal(a.traversable, b.traversable) and np.array_equal(a.reachable, b.reachable)
    ch = a.channels()
    assert ch.shape == (2, *detector.grid.shape) and ch.dtype == np.float32


def test_channels_match_grid_of_other_detector() -> None:
    grid = GridSpec(ahead_m=20.0, side_m=8.0)
    det = TraversableRegionDetector(grid=grid)
    res = det.update(synthetic_scan(TrackScene()), Pose())
    assert res.traversable.shape == grid.shape == res.reachable.shape == res.positive_obstacles.shape


# --- bad input -------------------------------------------------------------------------------


def make_scan(ranges: np.ndarray, elev_deg=(-1.2, -0.4, 0.4, 1.2)) -> StructuredScan:
    rig = LuxRig()
    az = np.radians(np.linspace(-55.0, 55.0, ranges.shape[1])) if ranges.shape[1] else np.zeros(0)
    return StructuredScan(
        sensor="lux",
        ranges_m=ranges,
        azimuth_rad=az,
        elevation_rad=np.radians(elev_deg),
        rotation=rig.rotation,
        translation_m=rig.translation_m,
    )


def test_empty_scan_gives_empty_result(detector) -> None:
    res = run(detector, make_scan(np.zeros((4, 0))))
    assert res.left_line is None and res.right_line is None and res.obstacles == []
    assert res.polygon_m.shape == (0, 2)
    assert not res.traversable.any() and not res.reachable.any()


def test_all_nan_scan_is_no_return(detector) -> None:
    res = run(detector, make_scan(np.full((4, 441), np.nan)))
    assert res.left_line is None and not res.traversable.any()


def test_nan_returns_are_skipped(detector) -> None:
    scan = synthetic_scan(TrackScene())
    ranges = scan.ranges_m.copy()
    ranges[:, ::7] = np.nan  # dropouts
    res = run(detector, make_scan(ranges))
    assert abs(res.left_line.x_at(10.0) + 4.0) < 0.2


def test_ranges_beyond_the_lux_reach_are_no_return(detector) -> None:
    # A 1e7 m range is no LUX return (it reaches 200 m); it must neither crash the Hough
    # accumulator (whose rho axis spans the points) nor change the result.
    ranges = synthetic_scan(TrackScene()).ranges_m.copy()
    ranges[:, 100] = np.nan
    expected = run(detector, make_scan(ranges))
    ranges[:, 100] = 1e7
    res = run(detector, make_scan(ranges))
    assert np.array_equal(res.raw_left_m, expected.raw_left_m, equal_nan=True)
    assert np.array_equal(res.traversable, expected.traversable)
    assert res.obstacles == expected.obstacles == []


def test_filters_keep_estimate_through_an_empty_frame() -> None:
    det = TraversableRegionDetector()
    first = det.update(synthetic_scan(TrackScene()), Pose())
    second = det.update(make_scan(np.full((4, 441), np.nan)), Pose())
    assert np.array_equal(first.left_points_m, second.left_points_m)
    assert second.left_line is not None


def test_ego_motion_carries_the_held_boundary_points_along_the_road_edge() -> None:
    """With ``kalman_ego_motion`` the estimates a frame without returns holds keep their distances
    ahead and lie on the last frame's boundary lines as seen from the new pose (here 1.9 m on and
    turned 10 deg left); by default (the paper's F = I) they stay where they were in the vehicle
    frame."""
    empty = make_scan(np.full((4, 441), np.nan))
    before, after = Pose(x=1.0, y=3.0, yaw=0.2), Pose(x=0.6, y=4.9, yaw=0.2 + math.radians(10.0))
    det = TraversableRegionDetector(TraversableConfig(kalman_ego_motion=True))
    first = det.update(synthetic_scan(TrackScene()), before)
    second = det.update(empty, after)
    for seen, held, line in (
        (first.left_points_m, second.left_points_m, first.left_line),
        (first.right_points_m, second.right_points_m, first.right_line),
    ):
        assert np.isfinite(seen).all()
        assert held[:, 1] == pytest.approx(seen[:, 1])
        ends = before.to_world(np.array([[line.x_at(0.0), 0.0, 0.0], [line.x_at(20.0), 20.0, 0.0]]))
        ends = after.to_vehicle(ends)[:, :2]  # the line, moved into the new vehicle frame
        x_on_line = ends[0, 0] + (held[:, 1] - ends[0, 1]) * (ends[1, 0] - ends[0, 0]) / (
            ends[1, 1] - ends[0, 1]
        )
        residual = np.abs(seen[:, 0] - line.x_at(seen[:, 1])).max()  # the fit's, kept by the carry
        assert held[:, 0] == pytest.approx(x_on_line, abs=2.0 * residual + 1e-9)
    assert second.left_line.x_at(10.0) > first.left_line.x_at(10.0) + 1.0  # a left turn moves it right
    still = TraversableRegionDetector()
    still.update(synthetic_scan(TrackScene()), before)
    assert np.array_equal(still.update(empty, after).left_points_m, first.left_points_m)


def test_a_carried_line_passing_the_lidar_on_the_wrong_side_restarts() -> None:
    """The car drives between the boundaries (paper T's A1), so a carried line that passes the
    LiDAR less than ``kalman_carry_min_clearance_m`` out on its own side is dropped; here the car
    moves sideways across the left boundary (4 m left of it) during a frame without returns."""
    empty = make_scan(np.full((4, 441), np.nan))
    before = Pose(x=1.0, y=3.0, yaw=0.2)

    def moved_left(metres: float) -> Pose:
        x, y, _ = before.to_world(np.array([[-metres, 0.0, 0.0]]))[0]
        return Pose(x=float(x), y=float(y), yaw=before.yaw)

    for clearance, shift, kept in ((0.0, 5.0, False), (None, 5.0, True), (0.0, 3.0, True), (1.5, 3.0, False)):
        config = TraversableConfig(kalman_ego_motion=True, kalman_carry_min_clearance_m=clearance)
        det = TraversableRegionDetector(config)
        det.update(synthetic_scan(TrackScene()), before)
        second = det.update(empty, moved_left(shift))
        assert np.isfinite(second.left_points_m).all() == kept, (clearance, shift)
        assert (second.left_line is not None) == kept
        assert np.isfinite(second.right_points_m).all()  # farther right of the car than before
        if kept:
            assert second.left_line.x_at(10.0) == pytest.approx(-4.0 + shift, abs=0.3)


def test_bad_ego_motion_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="kalman_ego_motion"):
        TraversableConfig(kalman_ego_motion=1)
    for angle in (0.0, 90.0, math.nan):
        with pytest.raises(ValueError, match="kalman_carry_max_angle_deg"):
            TraversableConfig(kalman_carry_max_angle_deg=angle)
    for clearance in (math.inf, math.nan, "0.5", True):
        with pytest.raises(ValueError, match="kalman_carry_min_clearance_m"):
            TraversableConfig(kalman_carry_min_clearance_m=clearance)


def test_wrong_layer_count_raises(detector) -> None:
    scan = StructuredScan(
        sensor="x", ranges_m=np.ones((3, 5)), azimuth_rad=np.arange(5.0), elevation_rad=np.zeros(3)
    )
    with pytest.raises(ValueError, match="4-layer"):
        detector.update(scan, Pose())


def test_descending_elevations_raise(detector) -> None:
    with pytest.raises(ValueError, match="ascending elevation"):
        detector.update(make_scan(np.ones((4, 5)), elev_deg=(1.2, 0.4, -0.4, -1.2)), Pose())


def test_nan_pose_raises_naming_pose(detector) -> None:
    with pytest.raises(ValueError, match="pose"):
        detector.update(synthetic_scan(TrackScene()), Pose(x=float("nan")))
    bad = Pose()
    object.__setattr__(bad, "yaw", float("nan"))  # bypassing Pose's own check
    with pytest.raises(ScanError, match="pose"):
        detector.update(synthetic_scan(TrackScene()), bad)
    with pytest.raises(ScanError, match="pose"):
        detector.update(synthetic_scan(TrackScene()), (0, 0, 0, 0, 0, 0))


def test_not_a_scan_raises(detector) -> None:
    with pytest.raises(ScanError, match="StructuredScan"):
        detector.update(np.zeros((4, 10)), Pose())


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    cols=st.integers(min_value=0, max_value=60),
    data=st.data(),
)
def test_random_structured_scans_never_crash(detector, cols, data) -> None:
    values = data.draw(
        st.lists(
            st.one_of(st.just(float("nan")), st.floats(min_value=0.0, max_value=80.0)),
            min_size=4 * cols,
            max_size=4 * cols,
        )
    )
    ranges = np.array(values, dtype=np.float64).reshape(4, cols)
    res = run(detector, make_scan(ranges))
    g = detector.grid.shape
    assert res.traversable.shape == g and res.traversable.dtype == bool
    assert not (res.reachable & ~res.traversable).any()
    for c in res.obstacles:
        assert np.isfinite(c.points_m).all() and c.points_m.shape[0] >= detector.config.min_cluster_points
    for side in (res.left_points_m, res.right_points_m):
        assert side.shape == (len(TraversableConfig().boundary_layers), 2)


def test_held_obstacles_stay_in_the_positive_grid_where_they_are_then_expire() -> None:
    """With ``obstacle_hold_s`` the car seen at 10 m stays marked after the LUX loses it (an empty
    frame), moved into the new vehicle frame by the pose, until the hold runs out."""
    seen = synthetic_scan(TrackScene(boxes=(CAR,)))
    empty = make_scan(np.full((4, 441), np.nan))
    det = TraversableRegionDetector(TraversableConfig(obstacle_hold_s=0.5))
    first = det.update(seen, Pose())
    assert first.positive_obstacles[grid_cell(det, 0.0, 10.0)]
    moved = Pose(y=2.0)  # 2 m on along the world's +Y (the vehicle's forward axis at yaw 0)
    held = det.update(dataclasses.replace(empty, timestamp_s=0.3), moved)
    assert held.obstacles == []
    assert held.positive_obstacles[grid_cell(det, 0.0, 8.0)]  # the near face, 2 m nearer
    assert not held.positive_obstacles[grid_cell(det, 0.0, 10.0)]
    assert held.positive_obstacles.sum() == first.positive_obstacles.sum()
    assert not det.update(dataclasses.replace(empty, timestamp_s=0.9), moved).positive_obstacles.any()
    # Per frame (the paper's, the default): nothing held.
    per_frame = TraversableRegionDetector()
    per_frame.update(seen, Pose())
    later = per_frame.update(dataclasses.replace(empty, timestamp_s=0.3), moved)
    assert not later.positive_obstacles.any()


def test_reset_forgets_held_obstacles() -> None:
    det = TraversableRegionDetector(TraversableConfig(obstacle_hold_s=5.0))
    det.update(synthetic_scan(TrackScene(boxes=(CAR,))), Pose())
    det.reset()
    assert not det.update(make_scan(np.full((4, 441), np.nan)), Pose()).positive_obstacles.any()


@pytest.mark.parametrize("hold", [-0.1, math.nan, math.inf])
def test_bad_obstacle_hold_is_refused(hold) -> None:
    with pytest.raises(ValueError, match="obstacle_hold_s"):
        TraversableConfig(obstacle_hold_s=hold)


def test_outputs_pinned_on_a_noisy_drive() -> None:
    # Pins this detector's output bit for bit on 8 frames of a bending, rutted, bumpy track with
    # a car and a pole, range noise and pitch (a speed-up must not change a single cell): every
    # frame's four grids hashed, their cell counts, obstacle counts and the last frame's lines.
    import hashlib

    rng = np.random.default_rng(4)
    bumps = random_bumps(rng, amplitude_m=0.03, wavelength_m=1.5)
    car = Box(x_m=0.5, y_m=14.0, size_x_m=1.8, size_y_m=4.5, height_m=1.5)
    pole = Box(x_m=-2.0, y_m=9.0, size_x_m=0.3, size_y_m=0.3, height_m=1.2)
    det = TraversableRegionDetector()
    digest, counts = hashlib.sha256(), []
    for i in range(8):
        scene = TrackScene(
            left_half_width_m=4.0 + 0.1 * i,
            border=("bank", "drop")[i % 2],
            bend_radius_m=60.0,
            rut_depth_m=0.04,
            bumps=bumps,
            travelled_m=0.7 * i,
            boxes=(car, pole)[: 1 + i % 2],
        )
        scan = synthetic_scan(
            scene, LuxRig(), vehicle_pitch_rad=math.radians(0.3 * (-1) ** i), range_noise_m=0.02, rng=rng
        )
        res = det.update(scan, Pose())
        grids = (res.traversable, res.positive_obstacles, res.feasible, res.reachable)
        for grid in grids:
            digest.update(np.packbits(grid).tobytes())
        counts.append((*(int(g.sum()) for g in grids), len(res.obstacles)))
    assert counts == [
        (1665, 13, 920, 400, 2),
        (1606, 13, 866, 325, 2),
        (1637, 13, 937, 409, 1),
        (1579, 10, 898, 334, 2),
        (1587, 12, 953, 407, 1),
        (1554, 3, 977, 382, 1),
        (1606, 12, 973, 426, 1),
        (1546, 3, 957, 360, 1),
    ]
    assert digest.hexdigest() == "4de866b6c76e51faaf1fbb4ca3d3e46038f7ebd4ecc8f3ba6d3adb1e2a83ed12"
    lines = (res.left_line.slope, res.left_line.offset_m, res.right_line.slope, res.right_line.offset_m)
    expected = (0.16939944375421112, -5.328669418203182, 0.2090663820264309, 2.7660335521181785)
    np.testing.assert_allclose(lines, expected, rtol=0.0, atol=1e-12)
