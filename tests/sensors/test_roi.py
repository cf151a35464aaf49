"""ROI casting: the rays cast equal the native scan's, every native return in the region is cast,
and paper N's detector sees the same pit frame by frame on ROI and native scans."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.detector import NegativeDetectorConfig, NegativeObstacleDetector
from negobs_gym.errors import ConfigError
from negobs_gym.sensors.lidar import scan as scan_one
from negobs_gym.sensors.lidar import scan_rig, start_rig_scan
from negobs_gym.sensors.noise import NoiseConfig, apply_keyed_noise
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.rigs import Rig, paper_n_rig, paper_t_rig
from negobs_gym.sensors.roi import HeightEnvelope, RoiConfig, RoiSelector, dilate, tile_rays
from negobs_gym.sim import presets
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

GRID = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)  # the envs' observation grid
REGION = (-GRID.side_m, GRID.side_m, -GRID.back_m, GRID.ahead_m)
RIG = Rig(name="native+lux", mounts=paper_n_rig().mounts + paper_t_rig().mounts)


def test_tile_z_spans_match_sampling_along_the_rays():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:50, 0] = 0.0  # rays parallel to a slab
    d[:50] /= np.linalg.norm(d[:50], axis=1, keepdims=True)
    origin = np.array([0.0, 0.0, 2.0])
    lo, hi = np.array([-3.0, -1.0, -0.5]), np.array([3.0, 20.0, 0.5])
    rays = tile_rays(origin, d, (lo[0], hi[0], lo[1], hi[1]), 30.0)
    got = np.zeros(len(d), bool)
    got[rays.index[(rays.z_min_m <= hi[2]) & (rays.z_max_m >= lo[2])]] = True
    t = np.linspace(0.0, 30.0, 6001)
    pts = origin + t[None, :, None] * d[:, None, :]
    sampled = ((pts >= lo) & (pts <= hi)).all(axis=2).any(axis=1)
    assert np.array_equal(got | sampled, got)  # every sampled hit is found
    assert (got & ~sampled).sum() <= 0.01 * len(d)  # misses only by grazing between samples


def test_keyed_noise_is_per_ray_and_has_the_configured_statistics():
    cfg = NoiseConfig()
    idx = np.arange(200_000)
    full = apply_keyed_noise(np.full(idx.size, 10.0), idx, cfg, key=42)
    part = apply_keyed_noise(np.full(1000, 10.0), idx[5000:6000], cfg, key=42)
    np.testing.assert_array_equal(full[5000:6000], part)
    assert np.nanstd(full) == pytest.approx(cfg.range_sigma_m, rel=0.02)
    assert np.isnan(full).mean() == pytest.approx(cfg.dropout_prob, rel=0.1)
    other = apply_keyed_noise(np.full(idx.size, 10.0), idx, cfg, key=43)
    assert not np.array_equal(full, other, equal_nan=True)


def test_config_rejects_bad_region_and_margins():
    with pytest.raises(ConfigError, match="region_xy_m"):
        RoiConfig(region_xy_m=(1.0, -1.0, 0.0, 5.0))
    with pytest.raises(ConfigError, match="laser_margin"):
        RoiConfig(laser_margin=-1)
    with pytest.raises(ConfigError, match="height_step_m"):
        RoiConfig(height_step_m=float("nan"))


def test_bands_of_another_tile_count_are_refused_by_name():
    sel = RoiSelector(RIG, RoiConfig(region_xy_m=REGION))
    with pytest.raises(ConfigError, match=r"^bands: need one band per tile") as error:
        sel.subsets_for_bands([(0.0, 1.0)] * (len(sel.tiles) + 1))
    assert error.value.field == "bands" and isinstance(error.value, ValueError)


def test_upper_lasers_are_skipped_and_the_lux_is_cast_in_full():
    sel = RoiSelector(RIG, RoiConfig(region_xy_m=REGION))
    recent: list = []
    subsets = sel.subsets(-0.5, 0.5, recent)
    hdl64 = RIG.mount("hdl64").model
    mask = np.zeros(hdl64.n_lasers * hdl64.n_columns, bool)
    mask[subsets["hdl64"].index] = True
    per_laser = mask.reshape(hdl64.n_lasers, hdl64.n_columns).sum(axis=1)
    assert per_laser[-1] == 0 and per_laser[0] > 0  # above the horizon: nothing in the region
    assert subsets["hdl64"].size < 0.6 * mask.size
    assert subsets["lux"].size == RIG.mount("lux").model.n_lasers * RIG.mount("lux").model.n_columns
    assert sel.subsets(-0.4, 0.4, recent) is subsets  # a recent band containing the asked one serves it
    wider = sel.subsets(-1.5, 0.5, recent)
    assert wider is not subsets and wider["hdl64"].size >= subsets["hdl64"].size
    assert sel.subsets(-0.4, 0.4, recent) is wider  # the most recent set containing the asked one
    # another caller's history does not serve this one: without its own, it casts its own bands
    assert sel.subsets(-0.4, 0.4, []) is subsets  # the same widened bands, from the kept masks
    assert sel.subsets(-0.4, 0.4) is subsets


def _vehicle_at(world: World, distance_m: float, ditch_y_m: float) -> Vehicle:
    vehicle = Vehicle(world)
    sx, _, syaw = world.terrain.start_xy_yaw
    # front of the ditch ``distance_m`` ahead of the vehicle origin (track along +Y)
    vehicle.reset(Pose(x=sx, y=ditch_y_m - distance_m, yaw=syaw))
    world.step(30)
    return vehicle


@pytest.fixture(scope="module")
def ditch_world():
    terrain = presets.braking_track(ditch_distance_m=30.0, ditch_length_m=0.6, seed=4)
    with World(terrain) as world:
        yield world


def test_roi_scan_equals_native_on_every_cast_ray_and_covers_the_region(ditch_world):
    world = ditch_world
    outline = np.asarray(world.terrain.negative_obstacles[0].outline_xy_m)
    vehicle = _vehicle_at(world, 12.0, float(outline[:, 1].min()))
    caster = make_caster(world, "auto", exclude_body_ids=(vehicle.body_id,))
    sel = RoiSelector(RIG, RoiConfig(region_xy_m=REGION))
    heights = HeightEnvelope(world, exclude_body_ids=(vehicle.body_id,))
    pose = vehicle.true_pose()
    subsets = sel.subsets_for_bands(heights.bands(pose, sel.tiles))
    roi = scan_rig(RIG, caster, pose, rng=np.random.default_rng(9), subsets=subsets)
    native = scan_rig(RIG, caster, pose, rng=np.random.default_rng(9))
    cropped = scan_rig(RIG, caster, pose, rng=np.random.default_rng(9), subsets=subsets, crop=True)
    hdl64 = subsets["hdl64"]
    first_cast = int(hdl64.index.min() % RIG.mount("hdl64").model.n_columns)
    for bad in ((5, 2), (0, 10**6), (first_cast + 1, hdl64.columns[1])):  # the last drops rays cast
        with pytest.raises(ConfigError, match="columns"):
            scan_one(
                RIG.mount("hdl64"), caster, pose, rng=np.random.default_rng(9), rays=hdl64.index, columns=bad
            )
    n_rays = RIG.mount("hdl64").model.n_lasers * RIG.mount("hdl64").model.n_columns
    for bad_rays in (np.array([0, n_rays]), np.array([-1, 5]), np.array([[1, 2]]), np.array([0.5])):
        with pytest.raises(ConfigError, match="rays"):
            scan_one(RIG.mount("hdl64"), caster, pose, rng=np.random.default_rng(9), rays=bad_rays)
    p_remove(world, vehicle)  # the module's world is shared: leave it as it was
    for name, scan in cropped.items():  # the cast columns and their margin, nothing else
        start, stop = subsets[name].columns or (0, roi[name].shape[1])
        assert stop - start < roi[name].shape[1] or name == "lux"
        np.testing.assert_array_equal(scan.ranges_m, roi[name].ranges_m[:, start:stop])
        np.testing.assert_array_equal(scan.azimuth_rad, roi[name].azimuth_rad[start:stop])
        assert np.isnan(np.delete(roi[name].ranges_m, np.s_[start:stop], axis=1)).all()
        margin = RoiConfig().column_margin  # columns of no return either side, as in the full image
        edge = np.isnan(scan.ranges_m).all(axis=0)
        assert (start == 0 or edge[:margin].all()) and (stop == roi[name].shape[1] or edge[-margin:].all())
    for name, full in native.items():
        cast = np.zeros(full.ranges_m.size, bool)
        cast[subsets[name].index] = True
        cast = cast.reshape(full.shape)
        np.testing.assert_array_equal(roi[name].ranges_m[cast], full.ranges_m[cast])
        assert np.isnan(roi[name].ranges_m[~cast]).all()
        xy = np.where(full.valid[..., None], full.points_vehicle[..., :2], 1e6)
        _, _, inside = GRID.cell_of(xy)
        assert inside.any()
        assert not (inside & ~cast).any(), f"{name}: a native return inside the grid was not cast"


def test_detections_on_roi_scans_equal_native_frame_by_frame(ditch_world):
    """Approach a 0.6 m ditch from 20 m to 6 m: the detector's grid is the same on both scans,
    and on the ROI scans cropped to their cast columns (``crop=True``) everything is the same.

    The in-grid pairs are the same but for the bumps (paper N §3.1: a rise then a fall along one
    laser) that run past the cast window: a laser whose ring follows the ditch sees it as one bump
    hundreds of columns long, which the ROI scan cuts, so it finds none of its pairs.
    """
    world = ditch_world
    outline = np.asarray(world.terrain.negative_obstacles[0].outline_xy_m)
    near_y = float(outline[:, 1].min())
    config = NegativeDetectorConfig(grid=GRID)
    det_roi, det_native = NegativeObstacleDetector(config), NegativeObstacleDetector(config)
    det_cropped = NegativeObstacleDetector(config)
    sel = RoiSelector(RIG, RoiConfig(region_xy_m=REGION))
    seen = pairs_seen = native_pairs = missing = 0
    vehicle = None
    for k, distance in enumerate(np.arange(20.0, 5.9, -0.7)):  # 7 m/s at 10 Hz
        if vehicle is not None:
            p_remove(world, vehicle)
        vehicle = _vehicle_at(world, float(distance), near_y)
        caster = make_caster(world, "auto", exclude_body_ids=(vehicle.body_id,))
        heights = HeightEnvelope(world, exclude_body_ids=(vehicle.body_id,))
        pose = vehicle.true_pose()
        subsets = sel.subsets_for_bands(heights.bands(pose, sel.tiles))
        rng_seed = 100 + k
        roi = scan_rig(RIG, caster, pose, rng=np.random.default_rng(rng_seed), subsets=subsets)
        native = scan_rig(RIG, caster, pose, rng=np.random.default_rng(rng_seed))
        cropped = scan_rig(RIG, caster, pose, rng=np.random.default_rng(rng_seed), subsets=subsets, crop=True)
        a = det_roi.update(roi, pose)
        b = det_native.update(native, pose)
        c = det_cropped.update(cropped, pose)  # the range images cropped to the cast columns: the same
        np.testing.assert_array_equal(c.grid, a.grid)
        np.testing.assert_array_equal(c.pairs.a_m, a.pairs.a_m)
        np.testing.assert_array_equal(c.pairs.posterior, a.pairs.posterior)
        for name in a.frame_pairs:
            np.testing.assert_array_equal(c.frame_pairs[name].b_m, a.frame_pairs[name].b_m)
        np.testing.assert_array_equal(a.grid, b.grid, err_msg=f"frame at {distance} m")
        for name in a.frame_pairs:  # pairs outside the grid (B up to 20 m to the side) are not read
            got = {tuple(p) for p in _in_grid(a.frame_pairs[name].b_m)}
            want = {tuple(p) for p in _in_grid(b.frame_pairs[name].b_m)}
            assert got <= want, f"{name} at {distance} m: the ROI scan found pairs the native scan has not"
            native_pairs += len(want)
            missing += len(want - got)
        seen += int(a.grid.any())
        pairs_seen += int(any(len(_in_grid(p.b_m)) for p in a.frame_pairs.values()))
    # the comparison means something only if the ditch is found
    assert pairs_seen >= 8 and seen >= 3, (pairs_seen, seen)
    assert native_pairs > 1000 and missing <= 0.01 * native_pairs, (missing, native_pairs)
    p_remove(world, vehicle)


def _in_grid(points_m: np.ndarray) -> np.ndarray:
    return points_m[GRID.cell_of(points_m[:, :2])[2]]


def p_remove(world: World, vehicle: Vehicle) -> None:
    """Take a vehicle out of the world (the next one is placed fresh)."""
    import pybullet as p

    world.remove_step_hook(vehicle._pre_step)
    world._dynamic.remove(vehicle.body_id)
    p.removeBody(vehicle.body_id, physicsClientId=world.client_id)


def test_threaded_embree_cast_equals_one_thread(ditch_world):
    pytest.importorskip("embreex")
    from negobs_gym.sensors.lidar import scan_rays_world
    from negobs_gym.sensors.raycast.embree_backend import EmbreeCaster, EmbreeConfig

    mount = RIG.mount("hdl64")
    o, d = scan_rays_world(mount, Pose(x=0.0, y=10.0, z=0.3))
    one = EmbreeCaster.from_world(ditch_world, config=EmbreeConfig(threads=1)).cast(o, d, 120.0)
    two = EmbreeCaster.from_world(ditch_world, config=EmbreeConfig(threads=3)).cast(o, d, 120.0)
    np.testing.assert_array_equal(one, two)
    assert np.isfinite(one).mean() > 0.3
    with pytest.raises(ConfigError, match="threads"):
        EmbreeConfig(threads=0)


def test_a_started_rig_frame_gives_scan_rigs_scans_in_any_order(ditch_world):
    """``start_rig_scan`` casts the largest sensor on the caster's pool thread while the others are
    asked for: every scan equals ``scan_rig``'s (one thread) whatever the order."""
    pytest.importorskip("embreex")
    from negobs_gym.sensors.raycast.embree_backend import EmbreeCaster, EmbreeConfig

    ditch_y = float(np.asarray(ditch_world.terrain.negative_obstacles[0].outline_xy_m)[:, 1].min())
    vehicle = _vehicle_at(ditch_world, 12.0, ditch_y)
    one = EmbreeCaster.from_world(ditch_world, (vehicle.body_id,), config=EmbreeConfig(threads=1))
    two = EmbreeCaster.from_world(ditch_world, (vehicle.body_id,), config=EmbreeConfig(threads=2))
    sel = RoiSelector(RIG, RoiConfig(region_xy_m=REGION))
    pose = vehicle.true_pose()
    subsets = sel.subsets_for_bands(HeightEnvelope(ditch_world, (vehicle.body_id,)).bands(pose, sel.tiles))
    p_remove(ditch_world, vehicle)  # the module's world is shared: leave it as it was
    for subs in (None, subsets):
        expected = scan_rig(RIG, one, pose, rng=np.random.default_rng(9), subsets=subs, crop=True)
        frame = start_rig_scan(RIG, two, pose, rng=np.random.default_rng(9), subsets=subs, crop=True)
        assert frame.names == tuple(mt.name for mt in RIG.mounts)
        assert frame.started == "hdl64"  # the most rays, native or ROI
        asked = [frame.scan(name) for name in reversed(frame.names)]  # the LUX first, the HDL-64 last
        got = frame.result()
        assert list(got) == list(expected) and [got[n] for n in reversed(frame.names)] == asked
        for name, s in expected.items():
            np.testing.assert_array_equal(got[name].ranges_m, s.ranges_m)
            np.testing.assert_array_equal(got[name].azimuth_rad, s.azimuth_rad)
        assert np.isfinite(got["hdl64"].ranges_m).sum() > 10_000
        with pytest.raises(ConfigError, match="no sensor 'velodyne'"):
            frame.scan("velodyne")
    pybullet = make_caster(ditch_world, "pybullet", exclude_body_ids=(vehicle.body_id,))
    assert start_rig_scan(RIG, pybullet, pose, rng=np.random.default_rng(9)).started is None


@pytest.mark.parametrize("wrap", [False, True])
@pytest.mark.parametrize("margins", [(0, 0), (1, 2), (8, 16), (40, 3), (2, 900)])
def test_dilation_equals_scipys_maximum_filter(wrap, margins):
    from scipy.ndimage import maximum_filter

    rng = np.random.default_rng(len(margins) + margins[1])
    for shape in ((1, 1), (3, 1), (5, 7), (64, 400), (4, 1000)):
        for density in (0.0, 0.002, 0.05):
            mask = rng.random(shape) < density
            lm, cm = margins
            mode = ("constant", "wrap" if wrap else "constant")
            want = maximum_filter(mask, size=(2 * lm + 1, 2 * cm + 1), mode=mode, cval=False)
            np.testing.assert_array_equal(dilate(mask, lm, cm, wrap), want)


def _bands_numpy(heights: HeightEnvelope, pose: Pose, boxes_xy_m) -> list:
    """HeightEnvelope.bands spelled in numpy passes over the grid (the code before its kernel)."""
    res = heights.resolution_m
    boxes = np.asarray(boxes_xy_m, dtype=np.float64).reshape(-1, 4)
    x0, x1, y0, y1 = boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max()
    corners = pose.to_world(np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x0, y1, 0.0], [x1, y1, 0.0]]))
    lo, hi = corners.min(axis=0) - 2 * res, corners.max(axis=0) + 2 * res
    rows, cols = heights._slice(lo[0], hi[0], lo[1], hi[1])
    rot = pose.rotation
    xs = (heights.origin_m[0] + res * np.arange(cols.start, cols.stop) - pose.x)[None, :]
    ys = (heights.origin_m[1] + res * np.arange(rows.start, rows.stop) - pose.y)[:, None]
    top, bottom = heights.top[rows, cols] - pose.z, heights.bottom[rows, cols] - pose.z
    pad = 1.5 * res
    vx_plane, vy_plane = rot[0, 0] * xs + rot[1, 0] * ys, rot[0, 1] * xs + rot[1, 1] * ys
    vx = np.stack([vx_plane + rot[2, 0] * bottom, vx_plane + rot[2, 0] * top])
    vy = np.stack([vy_plane + rot[2, 1] * bottom, vy_plane + rot[2, 1] * top])
    plane = rot[0, 2] * xs + rot[1, 2] * ys
    z_top, z_bottom = plane + rot[2, 2] * top, plane + rot[2, 2] * bottom
    tilt = res * (abs(rot[0, 2]) + abs(rot[1, 2]))
    out = []
    for bx0, bx1, by0, by1 in boxes:
        inside = ((vx >= bx0 - pad) & (vx <= bx1 + pad) & (vy >= by0 - pad) & (vy <= by1 + pad)).any(0)
        zs = [float(z_bottom[inside].min()) - tilt, float(z_top[inside].max()) + tilt] if inside.any() else []
        out.append((min(zs), max(zs)) if zs else None)
    return out


def test_height_bands_equal_their_numpy_spelling_bit_for_bit(ditch_world):
    heights = HeightEnvelope(ditch_world)
    sel = RoiSelector(RIG, RoiConfig(region_xy_m=REGION))
    rng = np.random.default_rng(3)
    x0, x1, y0, y1 = ditch_world.terrain.heightfield.extent_m
    tiles_sets = (sel.tiles, [(-1.0, 1.0, 0.0, 2.0)], [(-5000.0, -4999.0, 0.0, 1.0)])  # last: off the map
    for _ in range(60):
        pose = Pose(
            x=rng.uniform(x0, x1), y=rng.uniform(y0, y1), z=rng.normal(0.0, 0.5),
            roll=rng.normal(0.0, 0.1), pitch=rng.normal(0.0, 0.1), yaw=rng.uniform(-np.pi, np.pi),
        )  # fmt: skip
        for tiles in tiles_sets:
            assert heights.bands(pose, tiles) == _bands_numpy(heights, pose, tiles)
    assert heights.bands(pose, tiles_sets[2]) == [None]
