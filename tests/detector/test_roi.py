"""ROI step of paper N's detector (Table 1 line 1) on analytic scans with vertical structure."""

import math

import numpy as np
import pytest

from negobs_gym.core import Pose
from negobs_gym.detector import NegativeDetectorConfig, NegativeObstacleDetector
from negobs_gym.detector import roi as roi_module
from negobs_gym.detector.roi import RoiConfig, build_ground_map, ray_sectors
from negobs_gym.detector.synthetic import Block, Hole, hdl32_side_scan, hdl64_scan
from negobs_gym.errors import ConfigError

WALL = Block(x0_m=4.0, x1_m=4.3, y0_m=5.0, y1_m=25.0, height_m=2.0)
CAR = Block(x0_m=-3.6, x1_m=-1.8, y0_m=10.0, y1_m=14.5, height_m=1.5)  # a parked car as a box
POLES = tuple(
    Block(x0_m=2.4, x1_m=2.5, y0_m=y, y1_m=y + 0.1, height_m=2.0) for y in np.arange(6.0, 21.0, 2.0)
)
STRUCTURE = (WALL, CAR, *POLES)
ROCK = Block(x0_m=-3.1, x1_m=-2.3, y0_m=8.0, y1_m=8.6, height_m=0.5)
PIT = Hole.ahead(12.0, width_m=1.0, length_m=1.0, depth_m=0.8)


def _frame(holes, blocks, rng):
    kw = {"blocks": blocks, "noise_sigma_m": 0.02, "rng": rng}
    return {
        "hdl64": hdl64_scan(holes, **kw),
        "hdl32_left": hdl32_side_scan(holes, side="left", **kw),
        "hdl32_right": hdl32_side_scan(holes, side="right", **kw),
    }


def _run(holes, blocks, roi=True, frames=3):
    rng = np.random.default_rng(0)
    # paper N without the ground checks, so the ROI step alone is what is tested
    detector = NegativeObstacleDetector(NegativeDetectorConfig.paper(roi=RoiConfig(enabled=roi)))
    return [detector.update(_frame(holes, blocks, rng), Pose()) for _ in range(frames)]


def _pit_pairs(detection) -> int:
    b = np.concatenate([p.b_m for p in detection.frame_pairs.values()])
    on = (np.abs(b[:, 0]) < 0.8) & (b[:, 1] > PIT.y0_m - 0.3) & (b[:, 1] < PIT.y1_m + 0.5)
    return int(on.sum())


def test_structure_on_flat_ground_gives_no_pairs_and_no_obstacle():
    for detection in _run([], STRUCTURE):
        assert all(len(p) == 0 for p in detection.frame_pairs.values()), {
            s: len(p) for s, p in detection.frame_pairs.items()
        }
        assert detection.obstacles == []
        assert not detection.grid.any()


def test_without_roi_the_same_structure_makes_pairs_and_false_obstacles():
    # the scene is a real test of the ROI: the bare paper N tests form pairs on the wall and poles
    last = _run([], STRUCTURE, roi=False)[-1]
    assert sum(len(p) for p in last.frame_pairs.values()) > 20
    assert len(last.obstacles) >= 1


def test_pit_among_structure_is_kept_with_all_its_pairs():
    with_structure = _run([PIT], STRUCTURE)[-1]
    bare = _run([PIT], (), roi=False)[-1]
    assert _pit_pairs(with_structure) == _pit_pairs(bare) > 10
    # every pair left is on the pit, and the pit is the one obstacle
    assert _pit_pairs(with_structure) == sum(len(p) for p in with_structure.frame_pairs.values())
    (ob,) = with_structure.obstacles
    np.testing.assert_allclose(
        ob.centre_xy_m, [0.0, 12.5], atol=0.3
    )  # pairs span the near rim to the back wall


def test_ground_map_marks_wall_and_keeps_pit_back_wall_and_far_rim():
    scans = _frame([PIT], (WALL,), np.random.default_rng(1))
    ground = build_ground_map([s.points_vehicle for s in scans.values()], 20.0, RoiConfig())
    # the wall's face above the tolerance is structure; the pit's back wall and the rim beyond are not
    assert ground.is_structure(np.array([[4.0, 12.0, 1.0], [4.0, 18.0, 0.5]])).all()
    back_wall = np.array([[0.0, 13.0, -0.1], [0.2, 13.0, -0.05], [0.0, 13.3, 0.0]])
    assert not ground.is_structure(back_wall).any()
    assert not ground.on_structure_cell(back_wall).any()
    # a pair spanning the wall (A before it, B behind, along one ray) is outside the ROI
    assert not ground.keep_pairs(np.array([[3.6, 12.0, 0.0]]), np.array([[4.8, 16.0, 0.0]]))[0]
    assert ground.keep_pairs(np.array([[0.0, 11.9, 0.0]]), np.array([[0.0, 13.0, -0.1]]))[0]


def test_shadow_behind_a_rock_is_not_a_pair():
    # the HDL-64's (A, B) across a rock's shadow: A the highest return on its top, B the next
    # laser's return, on the ground behind it: a range jump, but outside the ROI (a car's shadow
    # ends beyond 20 m for a sensor 2.2 m up; a 0.5 m rock's ends ~2 m behind it)
    scans = _frame([], (ROCK,), np.random.default_rng(2))
    ground = build_ground_map([s.points_vehicle for s in scans.values()], 20.0, RoiConfig())
    pts = scans["hdl64"].points_vehicle[np.argsort(scans["hdl64"].elevation_rad)]
    roof = (pts[..., 2] > 0.4) & (np.abs(pts[..., 0] + 2.7) < 0.5)
    lasers, cols = np.nonzero(roof)
    top = {c: laser for laser, c in zip(lasers, cols, strict=True)}  # highest roof laser per column
    a = np.array([pts[laser, c] for c, laser in top.items() if laser + 1 < len(pts)])
    b = np.array([pts[laser + 1, c] for c, laser in top.items() if laser + 1 < len(pts)])
    behind = np.isfinite(b).all(axis=1) & (b[:, 1] > ROCK.y1_m) & (np.hypot(b[:, 0], b[:, 1]) < 20.0)
    assert behind.sum() > 10
    assert not ground.keep_pairs(a[behind], b[behind]).any()
    # the same B with an A on the ground beyond the rock is ground (nothing stands between them)
    a_beyond = b[behind] - 0.4 * b[behind] / np.linalg.norm(b[behind], axis=1, keepdims=True)
    a_beyond[:, 2] = 0.0
    assert ground.keep_pairs(a_beyond, b[behind]).mean() > 0.8


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("sector_deg", 0.0),
        ("bin_m", -1.0),
        ("ground_tolerance_m", float("nan")),
        ("max_ground_slope_deg", 90.0),
    ],
)
def test_roi_config_rejects_bad_values(field, value):
    with pytest.raises(ConfigError, match=field):
        RoiConfig(**{field: value})


def test_ray_sectors_give_the_per_point_ground_map():
    # the HDL-64 above the vehicle origin gets one sector per ray; the side HDL-32s' sectors depend
    # on the range (no table); rays on a sector boundary are left to the per-point rule
    scans = _frame([PIT], STRUCTURE, np.random.default_rng(4))
    cfg = RoiConfig()
    table = ray_sectors(scans["hdl64"], cfg)
    assert table.shape == scans["hdl64"].ranges_m.shape
    assert ray_sectors(scans["hdl32_left"], cfg) is None
    assert (table == -1).any() and (table >= 0).mean() > 0.95  # every 50th 0.09 deg column: a boundary
    assert ray_sectors(scans["hdl64"], cfg) is table  # cached per geometry
    clouds = [s.points_vehicle for s in scans.values()]
    plain = build_ground_map(clouds, 20.0, cfg)
    for sectors in ([table, None, None], [np.full(table.shape, -1), None, None]):
        fast = build_ground_map(clouds, 20.0, cfg, sectors)
        np.testing.assert_array_equal(fast.ground_z_m, plain.ground_z_m)
        np.testing.assert_array_equal(fast.structure_before, plain.structure_before)
    wrong = build_ground_map(clouds, 20.0, cfg, [(table + 7) * (table >= 0), None, None])
    assert not np.array_equal(wrong.structure_before, plain.structure_before)  # the table is used
    with pytest.raises(ConfigError, match="sectors"):
        build_ground_map(clouds, 20.0, cfg, [table])
    with pytest.raises(ConfigError, match="one sector per point"):
        build_ground_map(clouds, 20.0, cfg, [table[:, :-1], None, None])


def test_the_polynomial_angle_stays_within_its_stated_error():
    t = np.linspace(-math.tan(math.pi / 8), math.tan(math.pi / 8), 400_001)
    approx = np.array([roi_module._atan_small(v) for v in t[::97]])
    assert np.abs(approx - np.arctan(t[::97])).max() < 1.5e-10
    assert 50 * 1.5e-10 < roi_module._FAST_SECTOR_GUARD_RAD  # the guard keeps a wide margin over it


@pytest.mark.parametrize("sector_deg", [0.001, 0.25, 0.5, 7.3, 45.0])
def test_fast_point_sectors_equal_the_exact_rule(sector_deg):
    """Random points and points on, and within 1e-15 ... 1e-8 rad of, every sector boundary."""
    rng = np.random.default_rng(11)
    sector = math.radians(sector_deg)
    boundaries = -math.pi + sector * np.arange(math.ceil(2 * math.pi / sector) + 1)
    parts = [rng.normal(size=(20_000, 2)) * 10.0, rng.uniform(-1e-3, 1e-3, (2_000, 2))]
    for r in (1e-6, 7.0, 1e4):
        for eps in (0.0, 1e-15, -1e-15, 1e-12, -1e-12, 1e-9, -1e-9, 1e-8, -1e-8):
            th = boundaries[:: max(1, len(boundaries) // 2000)] + eps
            parts.append(np.stack([r * np.cos(th), r * np.sin(th)], axis=1))
    parts.append(
        np.array([[0.0, 0.0], [-0.0, 0.0], [-1.0, 0.0], [-1.0, -0.0], [0.0, -1.0], [1.0, 1.0], [-3.0, -3.0]])
    )
    xy = np.ascontiguousarray(np.concatenate(parts))
    exact = np.floor((np.array([math.atan2(y, x) for x, y in xy]) + math.pi) / sector).astype(np.int64)
    np.testing.assert_array_equal(roi_module._xy_sectors(xy, sector), exact)
