import sys

import numpy as np
import pybullet as p
import pytest

from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, MissingDependencyError, ScanError, SimulationError
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.raycast.embree_backend import EmbreeCaster, EmbreeConfig
from negobs_gym.sensors.raycast.meshes import box_mesh, transform_mesh
from negobs_gym.sensors.raycast.pybullet_backend import PyBulletCaster
from negobs_gym.sim.presets import braking_track, pedestrian_near_dropoff
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

pytest.importorskip("embreex")


@pytest.fixture(scope="module")
def flat_world():
    world = World(braking_track(rough=False, ditch_distance_m=20.0))
    own = Vehicle(world)
    yield world, own
    world.close()


def _down(xy, z0=10.0):
    xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
    return np.column_stack([xy, np.full(len(xy), z0)]), np.tile([0.0, 0.0, -1.0], (len(xy), 1))


def test_missing_embreex_raises(monkeypatch, flat_world):
    monkeypatch.setitem(sys.modules, "embreex", None)
    monkeypatch.setitem(sys.modules, "embreex.rtcore_scene", None)
    with pytest.raises(MissingDependencyError, match="embreex"):
        EmbreeCaster.from_world(flat_world[0])
    with pytest.raises(MissingDependencyError, match="embreex"):
        make_caster(flat_world[0], backend="embree")
    assert isinstance(make_caster(flat_world[0], backend="auto"), PyBulletCaster)


def test_make_caster(flat_world):
    world, _ = flat_world
    assert isinstance(make_caster(world), EmbreeCaster)
    assert isinstance(make_caster(world, backend="pybullet"), PyBulletCaster)
    with pytest.raises(ConfigError, match="backend"):
        make_caster(world, backend="optix")


def test_ditch_floor_and_ground(flat_world):
    world, _ = flat_world
    caster = EmbreeCaster.from_world(world)
    ditch = world.terrain.negative_obstacles[0]
    cx, cy = ditch.centre_xy_m
    o, d = _down([[cx, cy], [cx, cy - 5.0]])
    r = caster.cast(o, d, 50.0)
    np.testing.assert_allclose(10.0 - r, [ditch.floor_z_m, 0.0], atol=1e-4)


def test_ground_from_the_terrain_grid_keeps_walls_sharp(flat_world):
    world, _ = flat_world
    ditch = world.terrain.negative_obstacles[0]
    cx = float(ditch.centre_xy_m[0])
    near_edge = float(ditch.outline_xy_m[:, 1].min())
    ys = near_edge + np.linspace(0.02, 0.2, 10)  # inside the ditch, within one physics cell of its edge
    o, d = _down(np.column_stack([np.full(ys.size, cx), ys]))
    fine = EmbreeCaster.from_world(world, config=EmbreeConfig(ground="terrain"))
    coarse = EmbreeCaster.from_world(world)
    assert fine.n_static_triangles > 4 * coarse.n_static_triangles
    np.testing.assert_allclose(10.0 - fine.cast(o, d, 50.0), ditch.floor_z_m, atol=1e-4)
    assert np.any(10.0 - coarse.cast(o, d, 50.0) > ditch.floor_z_m + 0.1)  # the 0.25 m cell slopes
    with pytest.raises(ConfigError, match="ground"):
        EmbreeConfig(ground="mesh")


def test_own_vehicle_excluded_other_bodies_hit_and_tracked(flat_world):
    world, own = flat_world
    pose = own.true_pose()
    o, d = _down([[pose.x, pose.y + 1.4]])  # straight down onto the roof
    seen = EmbreeCaster.from_world(world)
    blind = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id])
    roof = seen.cast(o, d, 50.0)[0]
    ground = blind.cast(o, d, 50.0)[0]
    assert 10.0 - roof > 1.0  # the roof, well above the ground
    assert abs((10.0 - ground) - 0.0) < 0.05
    # the body moves: the auto-updated scene follows it, a frozen one does not
    frozen = EmbreeCaster.from_world(world, config=EmbreeConfig(auto_update=False))
    own.reset(Pose(pose.x + 10.0, pose.y, 0.0, 0.0, 0.0, pose.yaw))
    try:
        assert abs(10.0 - seen.cast(o, d, 50.0)[0]) < 0.05
        assert frozen.cast(o, d, 50.0)[0] == pytest.approx(roof, abs=1e-4)
        assert frozen.update_dynamic() is True
        assert abs(10.0 - frozen.cast(o, d, 50.0)[0]) < 0.05
        o2, d2 = _down([[pose.x + 10.0, pose.y + 1.4]])
        assert seen.cast(o2, d2, 50.0)[0] == pytest.approx(roof, abs=1e-3)
    finally:
        own.reset(pose)


def test_positive_obstacles_hit_like_pybullet():
    with World(pedestrian_near_dropoff(seed=1)) as world:
        (ped,) = world.terrain.positive_obstacles
        assert ped.shape == "cylinder"
        embree = EmbreeCaster.from_world(world)
        bullet = PyBulletCaster(world.client_id)
        # a fan of horizontal rays at mid height through the pedestrian
        c = np.asarray(ped.centre_m)
        ang = np.linspace(-0.2, 0.2, 201)
        o = np.tile(c - [0.0, 5.0, 0.0], (ang.size, 1))
        d = np.column_stack([np.sin(ang), np.cos(ang), np.zeros_like(ang)])
        re, rb = embree.cast(o, d, 30.0), bullet.cast(o, d, 30.0)
        on_ped = np.isfinite(rb) & (rb < 6.0)
        assert on_ped.sum() > 10
        np.testing.assert_array_equal(np.isfinite(re), np.isfinite(rb))
        assert np.nanmax(np.abs(re[on_ped] - rb[on_ped])) < 0.01


def test_direct_mesh_far_from_origin_keeps_precision():
    # float32 would lose ~1 cm at 1e5 m; the local origin keeps it exact
    v, f = transform_mesh(box_mesh(np.array([1.0, 1.0, 1.0])), np.eye(3), np.array([1e5, 2e5, 0.0]))
    caster = EmbreeCaster(v, f)
    o = np.array([[1e5 + 0.123, 2e5 - 0.456, 11.0]])
    r = caster.cast(o, np.array([[0.0, 0.0, -1.0]]), 20.0)
    assert r[0] == pytest.approx(10.0, abs=1e-4)
    assert np.isnan(caster.cast(o, np.array([[0.0, 0.0, 1.0]]), 20.0)[0])
    assert np.isnan(caster.cast(o, np.array([[0.0, 0.0, -1.0]]), 9.5)[0])  # beyond max range


def test_bad_input():
    v, f = box_mesh(np.ones(3))
    caster = EmbreeCaster(v, f)
    with pytest.raises(ScanError, match="finite"):
        caster.cast(np.array([[np.nan, 0, 0]]), np.array([[0, 0, 1.0]]), 10.0)
    with pytest.raises(ScanError, match="N, 3"):
        caster.cast(np.zeros((2, 2)), np.zeros((2, 2)), 10.0)
    with pytest.raises(ConfigError, match="vertices_m"):
        EmbreeCaster(np.full((3, 3), np.inf), np.array([[0, 1, 2]]))
    with pytest.raises(ConfigError, match="triangles"):
        EmbreeCaster(v, f + 100)
    with pytest.raises(ConfigError, match="max_chord_error_m"):
        EmbreeConfig(max_chord_error_m=0.0)


def test_unsupported_shape_raises():
    with World(braking_track(rough=False, ditch_distance_m=10.0)) as world:
        c = world.client_id
        v = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
        shape = p.createCollisionShape(
            p.GEOM_MESH, vertices=v, indices=[0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3], physicsClientId=c
        )
        p.createMultiBody(0, shape, basePosition=[0, 5, 1], physicsClientId=c)
        with pytest.raises(SimulationError, match="pybullet"):
            EmbreeCaster.from_world(world)


@pytest.mark.parametrize(
    ("geom", "kwargs"),
    [
        (p.GEOM_BOX, {"halfExtents": [0.4, 1.1, 0.7]}),
        (p.GEOM_SPHERE, {"radius": 0.6}),
        (p.GEOM_CYLINDER, {"radius": 0.35, "height": 1.7}),
        (p.GEOM_CAPSULE, {"radius": 0.3, "height": 1.2}),
        (p.GEOM_MESH, {"vertices": [[0, 0, 0], [1.5, 0, 0], [0, 1.2, 0], [0, 0, 1.0], [0.9, 0.9, 0.9]]}),
    ],
    ids=["box", "sphere", "cylinder", "capsule", "convex_mesh"],
)
def test_every_primitive_agrees_with_pybullet(geom, kwargs):
    """Rays from all around above ground at a tilted, yawed body (collision frame offset and turned).

    Origins stay above the terrain (PyBullet's heightfield is not hit from below, Embree's is).
    PyBullet's ray test on curved and hull shapes is an iterative convex cast and is itself off the
    true surface by ~0.1-1.4 mm median, ~5 mm at the 99th percentile (measured; boxes are exact),
    hence the per-body bar here; the scene-level 1 cm / 99.9 % bar is in test_agreement.py.
    """
    with World(braking_track(rough=False, ditch_distance_m=10.0)) as world:
        c = world.client_id
        shape = p.createCollisionShape(
            geom,
            collisionFramePosition=[0.1, -0.2, 0.05],
            collisionFrameOrientation=p.getQuaternionFromEuler([0.2, 0.4, -0.3]),
            physicsClientId=c,
            **kwargs,
        )
        orn = p.getQuaternionFromEuler([0.3, -0.2, 0.7])
        centre = np.array([1.0, 4.0, 2.0])
        p.createMultiBody(0, shape, basePosition=centre.tolist(), baseOrientation=orn, physicsClientId=c)
        rng = np.random.default_rng(0)
        n = 4000
        u = rng.normal(size=(n, 3))
        u[:, 2] = np.abs(u[:, 2])
        o = centre + 6.0 * u / np.linalg.norm(u, axis=1, keepdims=True)
        d = centre + rng.uniform(-1.0, 1.0, size=(n, 3)) - o
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        re = EmbreeCaster.from_world(world).cast(o, d, 20.0)
        rb = PyBulletCaster(c).cast(o, d, 20.0)
    body = np.isfinite(rb) & ((o + d * np.nan_to_num(rb)[:, None])[:, 2] > 0.05)  # not the ground
    assert body.sum() > 500
    assert np.mean(np.isfinite(re) == np.isfinite(rb)) >= 0.995
    dr = np.abs(re - rb)[body & np.isfinite(re)]
    assert np.mean(dr <= 0.01) >= 0.98
    assert np.median(dr) <= 0.002


def test_sphere_hits_match_the_exact_surface():
    """Embree's tessellated sphere against the analytic ray-sphere intersection.

    Chords lie <= 0.1 mm inside along each of the two tessellation directions, so a face centre
    is <= ~0.2 mm inside; at incidence below 60 deg that is <= 0.4 mm of range.
    """
    with World(braking_track(rough=False, ditch_distance_m=10.0)) as world:
        c = world.client_id
        r, centre = 0.4, np.array([0.5, 3.0, 1.5])
        shape = p.createCollisionShape(p.GEOM_SPHERE, radius=r, physicsClientId=c)
        p.createMultiBody(0, shape, basePosition=centre.tolist(), physicsClientId=c)
        rng = np.random.default_rng(1)
        o = centre + np.array([0.0, -5.0, 0.5])
        target = centre + rng.uniform(-0.3, 0.3, size=(2000, 3))
        d = target - o
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        got = EmbreeCaster.from_world(world).cast(np.tile(o, (2000, 1)), d, 20.0)
    oc = o - centre
    b = d @ oc
    disc = b * b - (oc @ oc - r * r)
    ok = disc > (0.5 * r) ** 2  # incidence below 60 deg
    exact = -b - np.sqrt(np.where(disc > 0, disc, np.nan))
    assert ok.sum() > 1000
    np.testing.assert_allclose(got[ok], exact[ok], atol=5e-4)
    assert np.all(got[ok] >= exact[ok] - 1e-5)  # the mesh lies inside the true surface


def test_deterministic_across_builds(flat_world):
    world, own = flat_world
    rng = np.random.default_rng(5)
    o = np.tile([0.0, 0.0, 2.2], (5000, 1))
    d = rng.normal(size=(5000, 3))
    a = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id]).cast(o, d, 120.0)
    b = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id]).cast(o, d, 120.0)
    np.testing.assert_array_equal(a, b)
    assert np.isfinite(a).sum() > 1000


def test_one_origin_for_every_ray_casts_as_the_same_origins_spelled_out(flat_world):
    world, _ = flat_world
    caster = EmbreeCaster.from_world(world)
    d = np.random.default_rng(1).normal(size=(5000, 3)) * [1.0, 1.0, 0.3] - [0.0, 0.0, 0.4]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = np.array([0.3, 2.0, 2.2])
    shared = caster.cast(np.broadcast_to(origin, d.shape), d, 80.0)
    np.testing.assert_array_equal(shared, caster.cast(np.tile(origin, (len(d), 1)), d, 80.0))
    assert np.isfinite(shared).mean() > 0.5
    with pytest.raises(ScanError, match="finite"):
        caster.cast(np.broadcast_to([np.nan, 0.0, 2.0], d.shape), d, 80.0)


def _rays(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3)) * [1.0, 1.0, 0.3] - [0.0, 0.0, 0.4]
    return np.tile([0.0, 0.0, 2.2], (n, 1)), d / np.linalg.norm(d, axis=1, keepdims=True)


def _record_pool_chunks(caster, fail=False):
    """Wrap the static scene's cast: an event set once a pool thread has cast a chunk (which then
    raises, with ``fail``)."""
    import threading

    scene, pool_cast = caster._static, threading.Event()
    own = scene.cast

    def cast(o, d, max_range_m, out=None):
        if threading.current_thread() is not threading.main_thread():
            pool_cast.set()
            if fail:
                raise RuntimeError("pool thread failed")
        return own(o, d, max_range_m, out=out)

    scene.cast = cast
    return pool_cast


@pytest.mark.parametrize("one_origin", [False, True], ids=["origin_per_ray", "one_origin"])
def test_a_started_cast_shares_its_rays_and_equals_one_thread_whatever_runs_beside_it(flat_world, one_origin):
    world, own = flat_world
    o, d = _rays(40_000, 3)
    if one_origin:  # a sensor's scan: one origin broadcast to every ray, passed on as one row
        o = np.broadcast_to(o[0], d.shape)
    o2, d2 = _rays(9_000, 4)
    one = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id], config=EmbreeConfig(threads=1))
    two = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id], config=EmbreeConfig(threads=2))
    expected, expected2 = one.cast(o, d, 120.0), one.cast(o2, d2, 120.0)
    pool_cast = _record_pool_chunks(two)
    pending = two.start_cast(o, d, 120.0)
    assert pool_cast.wait(timeout=30.0)  # the pool thread is casting while this thread is free
    beside = two.cast(o2, d2, 120.0)  # another cast on the calling thread meanwhile
    np.testing.assert_array_equal(pending.result(), expected)
    assert pending.result() is pending.result()  # cast once
    np.testing.assert_array_equal(beside, expected2)
    assert np.isfinite(expected).mean() > 0.5
    # one thread: start_cast defers the whole cast to result()
    np.testing.assert_array_equal(one.start_cast(o, d, 120.0).result(), expected)


def test_a_pool_threads_error_reaches_the_result(flat_world):
    world, own = flat_world
    o, d = _rays(40_000, 5)
    caster = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id], config=EmbreeConfig(threads=2))
    pool_cast = _record_pool_chunks(caster, fail=True)
    pending = caster.start_cast(o, d, 120.0)
    assert pool_cast.wait(timeout=30.0)
    with pytest.raises(RuntimeError, match="pool thread failed"):
        pending.result()


@pytest.mark.parametrize("threads", [1, 2])
def test_a_rotated_cast_equals_the_cast_of_the_rotated_rows_bit_for_bit(flat_world, threads):
    """A sensor's rays handed over as its direction table and the pose's rotation get the ranges of
    the same rays rotated first (``rotate_planes``), whole or as a subset."""
    from negobs_gym.core.pose import rotation_from_rpy
    from negobs_gym.sensors.lidar import rotate_planes

    world, own = flat_world
    caster = EmbreeCaster.from_world(
        world, exclude_body_ids=[own.body_id], config=EmbreeConfig(threads=threads)
    )
    rng = np.random.default_rng(11)
    d = rng.normal(size=(30_000, 3)) * [1.0, 1.0, 0.3] - [0.0, 0.0, 0.4]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    planes = tuple(np.ascontiguousarray(d[:, k]) for k in range(3))
    origin = np.array([0.4, 1.5, 2.1])
    for rpy in ((0.0, 0.0, 0.0), (0.03, -0.02, 1.3), (-0.1, 0.05, -2.9)):
        rot = rotation_from_rpy(*rpy)
        for index in (None, np.sort(rng.choice(len(d), 9_000, replace=False))):
            rows = rotate_planes(*planes, rot, index)
            want = caster.cast(np.broadcast_to(origin, rows.shape), rows, 80.0)
            got = caster.start_rotated_cast(origin, planes, index, rot, 80.0).result()
            np.testing.assert_array_equal(got, want)
            assert np.isfinite(got).mean() > 0.5


def test_a_rotated_cast_refuses_bad_rays(flat_world):
    world, _ = flat_world
    caster = EmbreeCaster.from_world(world)
    planes = (np.ones(4), np.zeros(4), np.zeros(4))
    eye = np.eye(3)
    with pytest.raises(ScanError, match="origin_m"):
        caster.start_rotated_cast(np.array([np.nan, 0.0, 2.0]), planes, None, eye, 50.0)
    with pytest.raises(ScanError, match="rotation"):
        caster.start_rotated_cast(np.zeros(3), planes, None, np.full((3, 3), np.inf), 50.0)
    with pytest.raises(ScanError, match="max_range_m"):
        caster.start_rotated_cast(np.zeros(3), planes, None, eye, -1.0)
    with pytest.raises(ScanError, match="index covers"):
        caster.start_rotated_cast(np.zeros(3), planes, np.array([0, 4]), eye, 50.0)
    with pytest.raises(ScanError, match="non-zero"):
        caster.start_rotated_cast(np.zeros(3), (np.zeros(4),) * 3, None, eye, 50.0)
    with pytest.raises(ScanError, match="finite"):
        caster.start_rotated_cast(np.zeros(3), (np.full(4, np.nan),) * 3, None, eye, 50.0)
