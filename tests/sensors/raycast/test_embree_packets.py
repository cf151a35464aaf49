import platform

import numpy as np
import pytest

from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.sensors.raycast import embree_packets
from negobs_gym.sensors.raycast.embree_backend import EmbreeCaster, EmbreeConfig, _Scene
from negobs_gym.sensors.raycast.meshes import heightfield_mesh
from negobs_gym.sim.presets import braking_track
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

pytest.importorskip("embreex")
pytestmark = pytest.mark.skipif(
    not embree_packets.packets_available(), reason="embreex's libembree4 not found: packets unused"
)


@pytest.fixture(scope="module")
def rough_world():
    world = World(braking_track(rough=True, ditch_distance_m=15.0))
    own = Vehicle(world)
    yield world, own
    world.close()


def _lidar_rays(origin, n_azimuth=1801, elevations_deg=None):
    elevations_deg = np.linspace(-25.0, 2.0, 37) if elevations_deg is None else elevations_deg
    az = np.linspace(-np.pi, np.pi, n_azimuth, endpoint=False)
    el = np.deg2rad(elevations_deg)[:, None]
    d = np.stack(np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), -1)
    d = d.reshape(-1, 3)
    return np.tile(origin, (len(d), 1)), d


def _both(mesh, o, d, tmax, width=None):
    packets = _Scene(mesh, packets=True, width=width)
    single = _Scene(mesh, packets=False)
    assert packets._packets is not None and single._embreex is not None
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    return packets.cast(o32, d32, tmax), single.cast(o32, d32, tmax)


def _frame_and_aimed_rays(mesh):
    """A LiDAR frame (66,637 rays: not a whole number of packets), then rays aimed exactly at the
    mesh's vertices and edge midpoints, where only robust traversal keeps a ray from slipping
    through; and the aimed rays' distances to their targets."""
    o, d = _lidar_rays(np.array([2.0, 0.5, 2.0]))
    v, f = mesh
    rng = np.random.default_rng(3)
    lo, hi = v[:, :2].min(axis=0) + 5.0, v[:, :2].max(axis=0) - 5.0  # inside the mesh, off its rim
    inner = np.flatnonzero(np.all((v[f[:, 0], :2] > lo) & (v[f[:, 0], :2] < hi), axis=1))
    tri = f[rng.choice(inner, 4000, replace=False)]
    targets = np.concatenate(
        [v[tri[:, 0]], 0.5 * (v[tri[:, 0]] + v[tri[:, 1]]), 0.5 * (v[tri[:, 1]] + v[tri[:, 2]])]
    )
    o2 = targets + rng.normal(size=targets.shape) * [6.0, 6.0, 0.0] + [0.0, 0.0, 2.5]
    d2 = targets - o2
    d2 /= np.linalg.norm(d2, axis=1, keepdims=True)
    return np.concatenate([o, o2]), np.concatenate([d, d2]), np.linalg.norm(targets - o2, axis=1)


def _rough_mesh(world):
    hf = world.physics_heightfield
    local = np.array([hf.origin_m[0] + 40 * hf.resolution_m, hf.origin_m[1] + 40 * hf.resolution_m, 0.0])
    return heightfield_mesh(hf, local)


@pytest.mark.parametrize("width", [None, *embree_packets.PACKET_WIDTHS])
def test_packets_equal_single_ray_queries_bit_for_bit(rough_world, width):
    world, _ = rough_world
    mesh = _rough_mesh(world)
    o, d, reach = _frame_and_aimed_rays(mesh)
    got, ref = _both(mesh, o, d, 120.0, width)
    np.testing.assert_array_equal(got, ref)
    n_frame = len(o) - len(reach)
    assert np.isfinite(got[:n_frame]).mean() > 0.5  # most of the frame hits the ground
    # float32 rounding lets a ray aimed at a peak pass just above it now and then
    assert np.mean(np.abs(got[n_frame:] - reach) < 1e-3) > 0.99


def _box_on(mesh, centre_local, half=(0.6, 0.4, 0.5)):
    """``mesh`` with a box standing on it at ``centre_local`` (x, y; its base 0.2 m into the
    ground), as a world's static body follows the terrain in the static mesh."""
    from negobs_gym.sensors.raycast.meshes import box_mesh, merge_meshes

    v = mesh[0]
    near = np.linalg.norm(v[:, :2] - centre_local, axis=1) < 1.0
    bv, bf = box_mesh(np.array(half))
    bv = bv + np.array([centre_local[0], centre_local[1], v[near, 2].mean() + half[2] - 0.2])
    return merge_meshes([mesh, (bv, bf)])


def test_the_fast_terrain_test_lets_no_ray_through(rough_world):
    """Rays aimed at the vertices and edges slip through the fast test's gaps; the repaired scene
    casts each of them again, so its hits and misses are the robust scene's and its ranges within
    the two tests' float32 rounding of them. A box on the terrain is in the mesh too."""
    world, _ = rough_world
    terrain = _rough_mesh(world)
    mesh = _box_on(terrain, terrain[0][:, :2].mean(axis=0))
    o, d, reach = _frame_and_aimed_rays(terrain)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    robust = embree_packets.PacketScene(*mesh).cast(o32, d32, 120.0)
    fast = embree_packets.PacketScene(*mesh, robust=False).cast(o32, d32, 120.0)
    slipped = np.isnan(fast) & ~np.isnan(robust) | (fast > robust + 0.01)
    assert slipped.sum() > 50  # the test's rays find the fast test's gaps
    scene = embree_packets.RepairedScene(*mesh, n_heightfield=len(terrain[1]))
    got = scene.cast(o32, d32, 120.0)
    # nothing slips through: no ray goes on past the robust hit (a slipped ray would, by metres)
    assert not (np.isnan(got) & ~np.isnan(robust)).any()
    assert not (got > robust + 1e-3).any()
    # a ray aimed exactly at a vertex grazes it within float32 rounding: one test may hit the
    # vertex where the other lets the ray pass just above it; every other range differs from the
    # robust scene's by the two tests' rounding only
    n_frame = len(o) - len(reach)
    differ = np.flatnonzero(~(np.abs(got - robust) <= 2e-6 * 120.0) & ~(np.isnan(got) & np.isnan(robust)))
    assert differ.size <= 0.002 * len(reach) and (differ >= n_frame).all()
    target = reach[differ - n_frame]
    assert (np.fmin(np.abs(got[differ] - target), np.abs(robust[differ] - target)) < 1e-3).all()
    both = ~np.isnan(robust) & ~np.isnan(got)
    assert (got[both] != robust[both]).sum() > 100  # most rays keep the fast test's own rounding


def test_the_rays_cast_again_are_misses_hits_from_below_and_hits_on_bodies(rough_world):
    """Which rays the fast test flags: a miss that ends under the ground (as a ray that slipped
    through it would), a hit on the terrain's underside (a ray from below the ground) and a hit on
    a body; a terrain hit from above and a ray toward the sky are kept. Flagged rays get the
    robust scene's range bit for bit."""
    world, _ = rough_world
    terrain = _rough_mesh(world)
    centre = terrain[0][:, :2].mean(axis=0)
    mesh = _box_on(terrain, centre)
    v = mesh[0]
    box_top = np.append(v[-8:, :2].mean(axis=0), v[-8:, 2].max())  # the box's 8 corners come last
    beside = np.array([centre[0] + 5.0, centre[1] + 5.0])
    ground = v[np.linalg.norm(v[:, :2] - beside, axis=1) < 0.5, 2].mean()
    top, under = np.append(beside, ground + 2.0), np.append(beside, ground - 1.5)
    scene = embree_packets.RepairedScene(*mesh, n_heightfield=len(terrain[1]))
    rays = {
        "down": (top, [0.1, 0.05, -1.0]),
        "sky": (top, [0.3, 0.1, 1.0]),
        "down, from under the ground": (under, [0.2, -0.1, -1.0]),
        "from below": (under, [0.05, 0.1, 1.0]),
        "on the box's top": (box_top + np.array([1.0, 0.5, 3.0]), [-1.0, -0.5, -3.0]),
    }
    o = np.array([r[0] for r in rays.values()], dtype=np.float32)
    d = np.array([r[1] for r in rays.values()], dtype=np.float64)
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    suspect = np.zeros(len(d), dtype=np.bool_)
    scene._fast._cast(o, d, 50.0, None, suspect, scene.n_heightfield, scene.ceilings, scene.tiles)
    assert dict(zip(rays, suspect.tolist(), strict=True)) == {
        "down": False,
        "sky": False,
        "down, from under the ground": True,
        "from below": True,
        "on the box's top": True,
    }
    got = scene.cast(o, d, 50.0)
    robust = embree_packets.PacketScene(*mesh).cast(o, d, 50.0)
    np.testing.assert_array_equal(got[suspect], robust[suspect])
    assert np.isfinite(got[[0, 3, 4]]).all() and np.isnan(got[[1, 2]]).all()
    with pytest.raises(ConfigError, match=r"^n_heightfield: needs 1 to"):
        embree_packets.RepairedScene(*mesh, n_heightfield=0)


def test_the_heightfield_ceilings_bound_every_point_of_the_surface(rough_world):
    """A miss is cast again when it ends below the ceiling of its tile: no point of any triangle
    may lie above its tile's ceiling, or a ray that slipped through there would be kept."""
    world, _ = rough_world
    v, f = _rough_mesh(world)
    ceilings, tiles = embree_packets._heightfield_ceilings(v.astype(np.float64), f.astype(np.int64))
    rng = np.random.default_rng(5)
    w = rng.dirichlet(np.ones(3), size=(len(f), 4))  # 4 random points on every triangle
    points = np.einsum("fkc,fcd->fkd", w, v[f]).reshape(-1, 3)
    points = np.concatenate([points, v])  # and every vertex
    i = np.clip(((points[:, 0] - tiles[0]) / tiles[2]).astype(int), 0, ceilings.shape[1] - 1)
    k = np.clip(((points[:, 1] - tiles[1]) / tiles[2]).astype(int), 0, ceilings.shape[0] - 1)
    assert (points[:, 2] <= ceilings[k, i]).all()
    assert tiles[3] == ceilings.max() and tiles[2] >= 2.0
    box = [v[:, 0].min(), v[:, 1].min(), v[:, 0].max(), v[:, 1].max()]  # the heightfield's own box
    np.testing.assert_array_equal(tiles[[0, 1, 4, 5]], box)
    assert ceilings.max() <= points[:, 2].max() + 0.01 + 1e-9  # each is some triangle's height
    assert np.median(ceilings) < ceilings.max() - 0.1  # and local: most tiles are lower than the top


@pytest.mark.parametrize("fast", [False, True])
def test_a_rays_distance_does_not_depend_on_the_rays_packed_with_it(rough_world, fast):
    """The ROI rig casts subsets of a frame: each ray must get the full frame's value, robust
    or with the fast terrain test (whose flagged rays are cast again in a smaller batch)."""
    world, _ = rough_world
    mesh = heightfield_mesh(world.physics_heightfield, np.zeros(3))
    scene = _Scene(mesh, packets=True, fast_heightfield=len(mesh[1]) if fast else 0)
    assert isinstance(scene._packets, embree_packets.RepairedScene) == fast
    o, d = _lidar_rays(np.array([1.0, 2.0, 2.0]))
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    full = scene.cast(o32, d32, 120.0)
    rng = np.random.default_rng(8)
    for subset in (rng.random(len(o)) < 0.3, np.arange(len(o)) % 7 == 3, np.arange(len(o)) >= 5):
        np.testing.assert_array_equal(scene.cast(o32[subset], d32[subset], 120.0), full[subset])


@pytest.mark.parametrize("width", embree_packets.PACKET_WIDTHS)
@pytest.mark.parametrize("n", [0, 1, 3, 7, 9, 15, 16, 17, 33])
def test_packet_remainders(rough_world, n, width):
    world, _ = rough_world
    hf = world.physics_heightfield
    mesh = heightfield_mesh(hf, np.zeros(3))
    o, d = _lidar_rays(np.array([5.0, 0.0, 2.0]), n_azimuth=64, elevations_deg=np.array([-10.0]))
    got, ref = _both(mesh, o[:n], d[:n], 60.0, width)
    assert got.shape == (n,)
    np.testing.assert_array_equal(got, ref)


def test_empty_mesh_hits_nothing():
    empty = (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    scene = embree_packets.PacketScene(*empty)
    got = scene.cast(np.zeros((3, 3), np.float32), np.ones((3, 3), np.float32), 9.5)
    assert got.shape == (3,) and np.isnan(got).all()


def test_caster_casts_the_same_with_and_without_packets(rough_world):
    world, own = rough_world
    # from beside the vehicle, which is not excluded: it is the caster's dynamic scene
    pose = own.true_pose()
    o, d = _lidar_rays(np.array([pose.x - 6.0, pose.y + 2.0, 2.2]), n_azimuth=900)
    casts = []
    for packets in (True, False):
        config = EmbreeConfig(ray_packets=packets, threads=2, fast_terrain=False)
        caster = EmbreeCaster.from_world(world, config=config)
        assert (caster._static._packets is not None) == packets
        assert caster._dynamic is not None and (caster._dynamic._packets is not None) == packets
        casts.append(caster.cast(o, d, 120.0))
    np.testing.assert_array_equal(casts[0], casts[1])
    assert np.isfinite(casts[0]).mean() > 0.5
    # the default, the fast terrain test: the same hits, the ranges within float32 rounding
    fast = EmbreeCaster.from_world(world, config=EmbreeConfig(threads=2))
    assert isinstance(fast._static._packets, embree_packets.RepairedScene)
    assert isinstance(fast._dynamic._packets, embree_packets.PacketScene)  # other vehicles: robust
    got = fast.cast(o, d, 120.0)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(casts[0]))
    np.testing.assert_allclose(got, casts[0], rtol=2e-6, atol=0.0)
    without_vehicle = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id]).cast(o, d, 120.0)
    assert (casts[0] < without_vehicle - 0.5).sum() > 20  # rays that stop on the vehicle


def test_without_the_library_the_caster_falls_back_to_embreex(monkeypatch, rough_world):
    world, own = rough_world
    o, d = _lidar_rays(np.array([0.0, 0.0, 2.2]), n_azimuth=300)
    robust = EmbreeConfig(fast_terrain=False)  # the fallback's scene: embreex's, robust
    caster = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id], config=robust)
    with_packets = caster.cast(o, d, 120.0)
    monkeypatch.setattr(embree_packets, "_library_candidates", lambda: [])
    monkeypatch.setattr(embree_packets, "_LIBRARY", [])
    assert not embree_packets.packets_available()
    assert embree_packets.native_packet_width() is None
    caster = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id])
    assert caster._static._packets is None
    np.testing.assert_array_equal(caster.cast(o, d, 120.0), with_packets)


def test_ray_packets_and_fast_terrain_must_be_bools():
    with pytest.raises(ConfigError, match="ray_packets"):
        EmbreeConfig(ray_packets=1)
    with pytest.raises(ConfigError, match="fast_terrain"):
        EmbreeConfig(fast_terrain="yes")
    for bad in (12, True, 8.0, "8"):
        with pytest.raises(ConfigError, match="packet_width"):
            EmbreeConfig(packet_width=bad)


def test_a_direct_mesh_names_its_heightfield_triangles(rough_world):
    world, _ = rough_world
    v, f = heightfield_mesh(world.physics_heightfield, np.zeros(3))
    assert isinstance(EmbreeCaster(v, f)._static._packets, embree_packets.PacketScene)  # robust
    fast = EmbreeCaster(v, f, heightfield_triangles=len(f))
    assert isinstance(fast._static._packets, embree_packets.RepairedScene)
    for bad in (-1, len(f) + 1, 2.5):
        with pytest.raises(ConfigError, match="heightfield_triangles"):
            EmbreeCaster(v, f, heightfield_triangles=bad)


@pytest.mark.parametrize("width", embree_packets.PACKET_WIDTHS)
def test_the_fast_terrain_test_casts_the_same_at_every_packet_width(rough_world, width):
    world, _ = rough_world
    mesh = heightfield_mesh(world.physics_heightfield, np.zeros(3))
    o, d = _lidar_rays(np.array([1.0, 2.0, 2.0]), n_azimuth=600)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    native = _Scene(mesh, packets=True, fast_heightfield=len(mesh[1]))
    pinned = _Scene(mesh, packets=True, fast_heightfield=len(mesh[1]), width=width)
    assert pinned._packets.width == width
    np.testing.assert_array_equal(pinned.cast(o32, d32, 120.0), native.cast(o32, d32, 120.0))


def test_the_default_packet_is_the_widest_the_kernels_cast_natively(rough_world):
    world, own = rough_world
    native = embree_packets.native_packet_width
    caster = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id])
    assert caster.packet_width == native() in embree_packets.PACKET_WIDTHS
    assert EmbreeCaster.from_world(world, config=EmbreeConfig(packet_width=4)).packet_width == 4
    assert EmbreeCaster.from_world(world, config=EmbreeConfig(ray_packets=False)).packet_width is None
    if platform.machine() in ("x86_64", "AMD64"):  # SSE's kernels are 4 rays wide, AVX2's 8
        assert native("sse4.2") == 4
        assert native("avx2") == 8
    with pytest.raises(ConfigError, match=r"^width: rays per packet"):
        embree_packets.PacketScene(*heightfield_mesh(world.physics_heightfield, np.zeros(3)), width=12)


def test_isa_config_is_checked():
    with pytest.raises(ConfigError, match="isa"):
        EmbreeConfig(isa="avx9")
    with pytest.raises(ConfigError, match="ray_packets"):
        EmbreeConfig(isa="avx2", ray_packets=False)


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 instruction sets")
def test_pinned_kernels_cast_the_same_scene_within_float32_rounding(rough_world):
    world, own = rough_world
    o, d = _lidar_rays(np.array([0.0, 0.0, 2.2]), n_azimuth=900)
    native = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id]).cast(o, d, 120.0)
    for isa in ("avx2", "sse4.2"):
        pinned = [
            EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id], config=EmbreeConfig(isa=isa)).cast(
                o, d, 120.0
            )
            for _ in range(2)
        ]
        np.testing.assert_array_equal(pinned[0], pinned[1])
        np.testing.assert_array_equal(np.isnan(pinned[0]), np.isnan(native))
        np.testing.assert_allclose(pinned[0], native, rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("packets", [True, False])
def test_one_origin_row_casts_as_the_origin_repeated_per_ray(rough_world, packets):
    """A sensor's rays share one origin: the scene takes it as one (1, 3) row."""
    world, _ = rough_world
    scene = _Scene(heightfield_mesh(world.physics_heightfield, np.zeros(3)), packets=packets)
    o, d = _lidar_rays(np.array([1.0, 2.0, 2.0]))
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    np.testing.assert_array_equal(scene.cast(o32[:1], d32, 120.0), scene.cast(o32, d32, 120.0))
    if packets:
        with pytest.raises(GeometryError, match=r"^origins: one per ray or one for all"):
            scene._packets.cast(o32[:2], d32, 120.0)
        with pytest.raises(ConfigError, match=r"^out: needs a float64 array"):
            scene._packets.cast(o32, d32, 120.0, out=np.empty(len(o), dtype=np.float32))


@pytest.mark.parametrize("packets", [True, False])
def test_a_range_counts_up_to_the_float32_step_past_the_limit_and_within_it(rough_world, packets):
    """Hits are kept where their float32 distance lies before the float32 step past max_range_m
    and, in float64, within max_range_m: cut at a limit that is not a float32 value, every kept
    range is <= the limit and every longer hit is NaN."""
    world, _ = rough_world
    scene = _Scene(heightfield_mesh(world.physics_heightfield, np.zeros(3)), packets=packets)
    o, d = _lidar_rays(np.array([1.0, 2.0, 2.0]))
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    far = scene.cast(o32, d32, 120.0)
    limit = float(np.nanmedian(far)) + 1e-9  # between two float32 values
    cut = scene.cast(o32, d32, limit)
    assert np.nanmax(cut) <= limit
    np.testing.assert_array_equal(cut[far <= limit], far[far <= limit])
    assert np.isnan(cut[~(far <= limit)]).all()
