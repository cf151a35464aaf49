"""LiDAR on simulator scenes (World + presets + the vehicle), with both ray-cast backends.

A 1 x 1 x 0.8 m pit centred 8 m ahead of the vehicle (paper N §4 sizes): the HDL-64 rings leave a
data gap over it, the side HDL-32 lines show a range jump across it; flat-ground ring radii are
h tan(beta) (Eq. 2); the side lasers' radial spacing at 10 m is at most half the HDL-64's ring gap.
"""

import warnings
from dataclasses import replace

import numpy as np
import pytest

from negobs_gym.sensors import NoiseConfig, hdl32e, hdl64e_s2, paper_n_rig
from negobs_gym.sensors.lidar import scan
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sim.presets import braking_track
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

OFF = NoiseConfig(enabled=False)
PIT_Y_M = 8.0
# the full native rig, ranges cut to 25 m: everything tested lies within 20 m, and PyBullet's
# heightfield ray test costs time in proportion to the ray length
RIG = paper_n_rig(hdl64=replace(hdl64e_s2(), max_range_m=25.0), hdl32=replace(hdl32e(), max_range_m=25.0))


@pytest.fixture(scope="module", params=[False, True], ids=["flat", "rough"])
def pit_world(request):
    terrain = braking_track(
        ditch_distance_m=PIT_Y_M - 0.5, ditch_length_m=1.0, ditch_width_m=1.0, rough=request.param
    )
    world = World(terrain)
    own = Vehicle(world)
    yield world, own, request.param, {}
    world.close()


def _scans(pit_world, backend):
    """Noise-free scans of the full native rig from the vehicle's pose (cached per backend)."""
    world, own, _, cache = pit_world
    if backend not in cache:
        caster = make_caster(world, backend=backend, exclude_body_ids=[own.body_id])
        pose = own.true_pose()
        cache[backend] = ({m.name: scan(m, caster, pose, noise=OFF) for m in RIG.mounts}, pose)
    return cache[backend]


def _nanmedian(a, axis):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(a, axis=axis)


@pytest.mark.parametrize("backend", ["pybullet", "embree"])
def test_pit_gap_and_range_jump(pit_world, backend):
    if backend == "embree":
        pytest.importorskip("embreex")
    world, _, rough, _ = pit_world
    scans, pose = _scans(pit_world, backend)
    (pit,) = world.terrain.negative_obstacles
    centre = pose.to_vehicle(np.array([*pit.centre_xy_m, 0.0]))[:2]
    assert np.allclose(centre, [0.0, PIT_Y_M], atol=0.2)
    around_xy = pit.centre_xy_m + np.array([[0.9, 0.0], [-0.9, 0.0], [0.0, 0.9], [0.0, -0.9]])
    rim_z = float(np.median(world.physics_heightfield.height_at(around_xy)))
    # HDL-64: no return near rim level inside the pit; its back wall and the ground around are seen
    p64 = scans["hdl64"].points_vehicle
    pw = pose.to_world(p64.reshape(-1, 3)).reshape(p64.shape)
    dx, dy = np.abs(p64[..., 0] - centre[0]), np.abs(p64[..., 1] - centre[1])
    ring_r = scans["hdl64"].translation_m[2] * np.tan(np.pi / 2 + scans["hdl64"].elevation_rad)
    assert np.any(np.abs(ring_r - PIT_Y_M) < 0.4)  # flat-ground rings would cross the pit ...
    assert not np.any((dx < 0.4) & (dy < 0.4) & (pw[..., 2] > rim_z - 0.1))  # ... but none lands there
    below_rim = (dx < 0.4) & (dy < 0.8) & (pw[..., 2] < rim_z - 0.1)
    assert below_rim.sum() > 20  # the rays went into the pit: its far wall
    assert np.any((dx < 0.4) & (dy > 0.8) & (dy < 2.0))  # ground in front of and behind it
    # side HDL-32s: along a laser line crossing the pit, the range jumps by > T32 = 0.30 m
    # (paper N §3.2; Eq. 8 gives up to w sqrt(1 + cot^2 beta) for a 1 m gap)
    for name in ("hdl32_left", "hdl32_right"):
        s = scans[name]
        pts = s.points_vehicle
        crossing = (np.abs(pts[..., 0] - centre[0]) < 0.45) & (np.abs(pts[..., 1] - centre[1]) < 0.55)
        rows = np.flatnonzero(crossing.any(axis=1))
        assert rows.size > 0, name
        jumps = np.abs(np.diff(s.ranges_m[rows], axis=1))
        assert np.nanmax(jumps) > 0.3, name
    if not rough:  # on flat ground, no laser line jumps that much away from the pit
        s = scans["hdl32_left"]
        pts = s.points_vehicle
        far = (np.abs(pts[..., 1] - centre[1]) > 3.0) & (pts[..., 1] > 3.0) & (pts[..., 1] < 15.0)
        r = np.where(far & (np.abs(pts[..., 2]) < 0.05), s.ranges_m, np.nan)
        d1 = np.diff(r, axis=1)
        assert np.nanmax(np.abs(np.diff(d1, axis=1))) < 0.3  # r_diff of paper N §3.2 stays below T32


@pytest.mark.parametrize("pit_world", [False], indirect=True, ids=["flat"])
@pytest.mark.parametrize("backend", ["pybullet", "embree"])
def test_flat_rings_and_side_spacing(pit_world, backend):
    if backend == "embree":
        pytest.importorskip("embreex")
    world = pit_world[0]
    scans, pose = _scans(pit_world, backend)
    s64 = scans["hdl64"]
    ground_z = float(world.physics_heightfield.height_at(np.array([pose.x, pose.y])))
    h = s64.translation_m[2] + pose.z - ground_z  # the vehicle origin rests ~1 cm above the ground
    p64 = s64.points_vehicle
    behind = (p64[..., 1] < -6.0) & (np.abs(p64[..., 0]) < 3.0)  # flat ground behind, away from the pit
    radius = np.hypot(p64[..., 0], p64[..., 1])
    med = _nanmedian(np.where(behind, radius, np.nan), axis=1)
    expected = h * np.tan(np.pi / 2 + s64.elevation_rad)  # Eq. 2
    ok = np.isfinite(med)
    assert ok.sum() >= 10
    np.testing.assert_allclose(med[ok], expected[ok], atol=0.01)
    # side spacing at 10 m vs the HDL-64 ring gap there (ring radii straight ahead)
    ring = np.sort(expected[(expected > 0) & (expected < 100)])
    k = np.searchsorted(ring, 10.0)
    gap64 = ring[k] - ring[k - 1]
    spacing = []
    for name in ("hdl32_left", "hdl32_right"):
        pts = scans[name].points_vehicle
        on_ground = np.abs(pts[..., 2] + pose.z - ground_z) < 0.05
        y = np.where(on_ground & (np.abs(pts[..., 1] - 10.0) < 1.0), pts[..., 1], np.nan)
        spacing.append(_nanmedian(np.diff(np.sort(y, axis=1), axis=1), axis=1))
    spacing = np.concatenate(spacing)
    assert np.isfinite(spacing).sum() >= 20
    assert np.nanmax(spacing) <= gap64 / 2
