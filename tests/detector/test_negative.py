"""NegativeObstacleDetector end to end on analytic scans (plane with a rectangular hole)."""

import dataclasses

import numpy as np
import pytest

from negobs_gym.core import GridSpec, Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector import NegativeDetectorConfig, NegativeObstacleDetector
from negobs_gym.detector.synthetic import Hole, hdl32_side_scan, hdl64_scan
from negobs_gym.errors import ConfigError, InterfaceError, ScanError

POSE0 = Pose(x=0.0, y=0.0, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)
PIT_8M = Hole.ahead(8.0, width_m=1.0, length_m=1.0, depth_m=0.8)


def _rig_scans(holes, rng=None, sigma=0.0):
    kw = {"noise_sigma_m": sigma, "rng": rng}
    return {
        "hdl64": hdl64_scan(holes, **kw),
        "hdl32_left": hdl32_side_scan(holes, side="left", **kw),
        "hdl32_right": hdl32_side_scan(holes, side="right", **kw),
    }


def _hole_cells(hole: Hole, grid: GridSpec) -> np.ndarray:
    c = grid.cell_centres()
    return (
        (c[..., 0] > hole.x0_m) & (c[..., 0] < hole.x1_m) & (c[..., 1] > hole.y0_m) & (c[..., 1] < hole.y1_m)
    )


def test_fused_rig_finds_the_pit_in_one_frame_and_marks_its_cells():
    detection = NegativeObstacleDetector().update(_rig_scans([PIT_8M]), POSE0)
    (ob,) = detection.obstacles
    np.testing.assert_allclose(ob.centre_xy_m, [0.0, 8.5], atol=0.15)
    assert 0.7 < ob.area_m2 < 1.5
    truth = _hole_cells(PIT_8M, detection.grid_spec)
    assert (detection.grid & truth).sum() >= 0.8 * truth.sum()
    # nothing marked more than a cell and a half away from the pit
    rows, cols = np.nonzero(detection.grid)
    xy = detection.grid_spec.cell_centres()[rows, cols]
    assert np.all(np.abs(xy[:, 0]) < 0.8) and np.all((xy[:, 1] > 7.7) & (xy[:, 1] < 9.3))
    # every obstacle pair is confirmed and indexes the fused pairs
    assert detection.pairs.confirmed[ob.pair_indices].all()


def test_hdl64_alone_needs_three_frames():
    detector = NegativeObstacleDetector(NegativeDetectorConfig(mode="hdl64"))
    results = [detector.update(_rig_scans([PIT_8M]), POSE0) for _ in range(3)]
    assert [len(r.obstacles) for r in results] == [0, 0, 1]
    assert set(results[-1].frame_pairs) == {"hdl64"}


def test_hdl32_mode_reads_only_the_side_sensors():
    # The side lasers fan out sideways, ~1.33 deg apart: at 8 m their pairs lie ~0.2 m apart, too few
    # within eps = 0.40 m for MinFPs = 4 (paper N Fig. 16: 32-only recall falls with distance); at
    # 6 m they are ~0.14 m apart and cluster.
    pit_6m = Hole.ahead(6.0, width_m=1.0, length_m=1.0, depth_m=0.8)
    for hole, found in ((PIT_8M, False), (pit_6m, True)):
        detector = NegativeObstacleDetector(NegativeDetectorConfig(mode="hdl32"))
        for _ in range(3):
            detection = detector.update(_rig_scans([hole]), POSE0)
        assert set(detection.frame_pairs) == {"hdl32_left", "hdl32_right"}
        assert detection.pairs.confirmed.sum() >= 4
        truth = _hole_cells(hole, detection.grid_spec)
        assert (detection.grid & truth).any() == found


def test_noisy_plane_gives_no_obstacle():
    rng = np.random.default_rng(0)
    detector = NegativeObstacleDetector()
    for _ in range(5):
        detection = detector.update(_rig_scans([], rng=rng, sigma=0.02), POSE0)
        assert detection.obstacles == [] and not detection.grid.any()


def test_history_follows_the_pose_while_driving():
    detector = NegativeObstacleDetector(NegativeDetectorConfig(mode="hdl64"))
    for k in range(4):  # drive 0.5 m per frame towards a pit fixed in the world at y = 10 m
        y = 0.5 * k
        hole = Hole.ahead(10.0 - y, width_m=1.0, length_m=1.0, depth_m=0.8)
        detection = detector.update(_rig_scans([hole]), Pose(x=0.0, y=y, z=0.0, roll=0.0, pitch=0.0, yaw=0.0))
    (ob,) = detection.obstacles
    np.testing.assert_allclose(ob.centre_xy_m, [0.0, 10.0 - 1.5 + 0.5], atol=0.2)


def test_reset_forgets_the_history():
    detector = NegativeObstacleDetector(NegativeDetectorConfig(mode="hdl64"))
    for _ in range(2):
        detector.update(_rig_scans([PIT_8M]), POSE0)
    detector.reset()
    assert detector.update(_rig_scans([PIT_8M]), POSE0).obstacles == []


def test_same_input_same_detection_bit_for_bit():
    def run():
        rng = np.random.default_rng(5)
        detector = NegativeObstacleDetector()
        return [detector.update(_rig_scans([PIT_8M], rng=rng, sigma=0.02), POSE0) for _ in range(3)]

    for d1, d2 in zip(run(), run(), strict=True):
        np.testing.assert_array_equal(d1.grid, d2.grid)
        np.testing.assert_array_equal(d1.pairs.a_m, d2.pairs.a_m)
        np.testing.assert_array_equal(d1.pairs.posterior, d2.pairs.posterior)


def test_other_sensors_in_the_mapping_are_ignored():
    scans = _rig_scans([PIT_8M])
    lux = dataclasses.replace(scans["hdl64"], sensor="lux")
    detection = NegativeObstacleDetector().update({**scans, "lux": lux}, POSE0)
    assert set(detection.frame_pairs) == {"hdl64", "hdl32_left", "hdl32_right"}


def test_empty_frames_and_scans_without_returns_give_no_pairs():
    detector = NegativeObstacleDetector()
    assert not detector.update({}, POSE0).grid.any()
    scan = hdl64_scan([])
    blind = StructuredScan(
        "hdl64",
        np.full_like(scan.ranges_m, np.nan),
        scan.azimuth_rad,
        scan.elevation_rad,
        rotation=scan.rotation,
        translation_m=scan.translation_m,
    )
    detection = detector.update({"hdl64": blind}, POSE0)
    assert len(detection.frame_pairs["hdl64"]) == 0 and not detection.grid.any()


def test_bad_input_raises_value_error_naming_it():
    detector = NegativeObstacleDetector()
    scans = _rig_scans([])
    with pytest.raises(ValueError, match="pose"):
        detector.update(scans, Pose(x=np.nan, y=0.0, z=0.0, roll=0.0, pitch=0.0, yaw=0.0))
    with pytest.raises(ValueError, match="none of the configured"):
        detector.update({"velodyne": scans["hdl64"]}, POSE0)
    with pytest.raises(ValueError, match="StructuredScan"):
        detector.update({"hdl64": np.zeros((64, 10))}, POSE0)
    with pytest.raises(InterfaceError, match=r"^config: must be a NegativeDetectorConfig") as bad:
        NegativeObstacleDetector(config={"mode": "fused"})
    assert isinstance(bad.value, TypeError)
    for coverage in ((0.0, 1.0, 2.0), (1.0, -1.0, 0.0, 20.0), (-6.0, 6.0, np.nan, 20.0), "far"):
        with pytest.raises(ScanError, match="coverage_xy_m"):
            detector.update(scans, POSE0, coverage)


def test_a_partial_frame_keeps_its_pairs_inside_the_coverage_and_the_history_outside_it():
    """A frame declared to cover only the ground beyond 12 m: the 8 m pit's pairs of this frame are
    dropped, but the pit confirmed by earlier whole frames stays in the grid (not missed where
    the frame did not look); a whole frame without it removes it."""
    detector = NegativeObstacleDetector()
    detector.update(_rig_scans([PIT_8M]), POSE0)
    far = (-6.4, 6.4, 12.0, 25.6)
    detection = detector.update(_rig_scans([PIT_8M]), POSE0, far)
    assert all(len(p) == 0 for p in detection.frame_pairs.values())
    truth = _hole_cells(PIT_8M, detection.grid_spec)
    assert (detection.grid & truth).sum() >= 0.8 * truth.sum()
    assert detector.update(_rig_scans([]), POSE0, far).grid.any()
    assert not detector.update(_rig_scans([]), POSE0).grid.any()


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"mode": "hdl16"}, "mode"),
        ({"hdl64_sensors": ["hdl64"]}, "hdl64_sensors"),
        ({"hdl32_sensors": ("hdl64",)}, "hdl32_sensors"),
        ({"grid": 0.2}, "grid"),
    ],
)
def test_bad_config(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        NegativeDetectorConfig(**kwargs)


def test_range_limit_bounds_a_and_the_far_wall_margin_lets_b_reach_beyond() -> None:
    from negobs_gym.detector.negative import within_roi
    from negobs_gym.detector.pairs import FeaturePairs

    a = np.array([[0.0, 19.0, 0.0], [0.0, 19.5, 0.0], [0.0, 20.5, 0.0]])
    b = np.array([[0.0, 20.2, -0.5], [0.0, 21.2, -0.5], [0.0, 21.3, -0.5]])
    pairs = FeaturePairs("hdl64", a, b, b + np.array([0.0, 0.2, 0.3]))
    assert len(within_roi(pairs, 20.0, None)) == 0  # default: B within 20 m as well
    kept = within_roi(pairs, 20.0, None, far_wall_margin_m=1.5)
    np.testing.assert_array_equal(kept.a_m, a[:2])  # the third pair's A is beyond 20 m
    with pytest.raises(ConfigError, match="far_wall_margin_m"):
        NegativeDetectorConfig(far_wall_margin_m=-1.0)


def test_side_hdl32_pairs_may_end_past_the_range_limit_on_a_pit_at_its_edge() -> None:
    # near rim at 19.2 m, back wall at 20.2 m: the side HDL-32s' B lies past max_range_m (20 m) and
    # is kept within hdl32_far_wall_margin_m (1.5 m); the HDL-64's margin stays 0
    pit = [Hole.ahead(19.2, width_m=1.0, length_m=1.0, depth_m=0.8)]
    scans = _rig_scans(pit)
    found = NegativeObstacleDetector().update(scans, POSE0).frame_pairs
    for side in ("hdl32_left", "hdl32_right"):
        b_range = np.hypot(found[side].b_m[:, 0], found[side].b_m[:, 1])
        assert len(b_range) > 0 and b_range.max() > 20.0
    assert np.all(np.hypot(found["hdl64"].b_m[:, 0], found["hdl64"].b_m[:, 1]) <= 20.0)
    paper = NegativeObstacleDetector(NegativeDetectorConfig(hdl32_far_wall_margin_m=0.0))
    assert all(len(paper.update(scans, POSE0).frame_pairs[s]) == 0 for s in ("hdl32_left", "hdl32_right"))
    with pytest.raises(ConfigError, match="hdl32_far_wall_margin_m"):
        NegativeDetectorConfig(hdl32_far_wall_margin_m=float("nan"))


@pytest.mark.parametrize("tighten", [False, True])
def test_near_edge_of_a_pit_confirmed_far_out(tighten: bool) -> None:
    # A pit fixed in the world at y = 18 m, approached 0.7 m per frame to 8 m: its first pairs'
    # A lies up to a ring gap (~1 m at 18 m) before the rim. Paper N's history keeps that early
    # edge; tighten_on_match moves it to the close frames' A (ring gap ~0.3 m at 8 m).
    fusion = dataclasses.replace(NegativeDetectorConfig().fusion, tighten_on_match=tighten)
    detector = NegativeObstacleDetector(NegativeDetectorConfig(mode="hdl64", fusion=fusion))
    for k in range(15):
        y = 0.7 * k
        hole = Hole.ahead(18.0 - y, width_m=1.5, length_m=1.0, depth_m=0.8)
        detection = detector.update(_rig_scans([hole]), Pose(x=0.0, y=y, z=0.0, roll=0.0, pitch=0.0, yaw=0.0))
    (ob,) = detection.obstacles
    lead_m = hole.y0_m - ob.outline_xy_m[:, 1].min()
    if tighten:
        assert -0.05 < lead_m < 0.4
    else:
        assert lead_m > 0.6
    assert ob.outline_xy_m[:, 1].max() == pytest.approx(hole.y1_m, abs=0.3)  # the far rim either way


def test_a_scan_that_did_not_move_while_firing_gives_the_same_detection():
    scans = _rig_scans([PIT_8M])
    still = NegativeObstacleDetector().update(scans, POSE0)
    motion = np.zeros((scans["hdl64"].shape[1], 3, 4))
    motion[:, :, :3] = np.eye(3)
    moving = dict(scans, hdl64=dataclasses.replace(scans["hdl64"], column_motion=motion))
    same = NegativeObstacleDetector().update(moving, POSE0)
    for name, pairs in still.frame_pairs.items():
        np.testing.assert_array_equal(same.frame_pairs[name].a_m, pairs.a_m)
        np.testing.assert_array_equal(same.frame_pairs[name].b_m, pairs.b_m)
    np.testing.assert_array_equal(same.grid, still.grid)
