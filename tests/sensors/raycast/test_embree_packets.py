import platform

import numpy as np
import pytest

from negobs_gym.errors import ConfigError
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


def _both(mesh, o, d, tmax):
    packets = _Scene(mesh, packets=True)
    single = _Scene(mesh, packets=False)
    assert packets._packets is not None and single._embreex is not None
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    return packets.cast(o32, d32, tmax), single.cast(o32, d32, tmax)


def test_packets_equal_single_ray_queries_bit_for_bit(rough_world):
    world, _ = rough_world
    hf = world.physics_heightfield
    local = np.array([hf.origin_m[0] + 40 * hf.resolution_m, hf.origin_m[1] + 40 * hf.resolution_m, 0.0])
    mesh = heightfield_mesh(hf, local)
    # a LiDAR frame (66,637 rays: not a whole number of packets), and rays aimed exactly at the
    # mesh's vertices and edge midpoints, where only robust traversal keeps a ray from slipping through
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
    got, ref = _both(mesh, np.concatenate([o, o2]), np.concatenate([d, d2]), 120.0)
    np.testing.assert_array_equal(got, ref)
    assert np.isfinite(got[: len(o)]).mean() > 0.5  # most of the frame hits the ground
    aimed = got[len(o) :]
    reach = np.linalg.norm(targets - o2, axis=1)
    # float32 rounding lets a ray aimed at a peak pass just above it now and then
    assert np.mean(np.abs(aimed - reach) < 1e-3) > 0.99


def test_a_rays_distance_does_not_depend_on_the_rays_packed_with_it(rough_world):
    """The ROI rig casts subsets of a frame: each ray must get the full frame's value."""
    world, _ = rough_world
    scene = _Scene(heightfield_mesh(world.physics_heightfield, np.zeros(3)), packets=True)
    o, d = _lidar_rays(np.array([1.0, 2.0, 2.0]))
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    full = scene.cast(o32, d32, 120.0)
    rng = np.random.default_rng(8)
    for subset in (rng.random(len(o)) < 0.3, np.arange(len(o)) % 7 == 3, np.arange(len(o)) >= 5):
        np.testing.assert_array_equal(scene.cast(o32[subset], d32[subset], 120.0), full[subset])


@pytest.mark.parametrize("n", [0, 1, 15, 16, 17, 33])
def test_packet_remainders(rough_world, n):
    world, _ = rough_world
    hf = world.physics_heightfield
    mesh = heightfield_mesh(hf, np.zeros(3))
    o, d = _lidar_rays(np.array([5.0, 0.0, 2.0]), n_azimuth=64, elevations_deg=np.array([-10.0]))
    got, ref = _both(mesh, o[:n], d[:n], 60.0)
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
        caster = EmbreeCaster.from_world(world, config=EmbreeConfig(ray_packets=packets, threads=2))
        assert (caster._static._packets is not None) == packets
        assert caster._dynamic is not None and (caster._dynamic._packets is not None) == packets
        casts.append(caster.cast(o, d, 120.0))
    np.testing.assert_array_equal(casts[0], casts[1])
    assert np.isfinite(casts[0]).mean() > 0.5
    without_vehicle = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id]).cast(o, d, 120.0)
    assert (casts[0] < without_vehicle - 0.5).sum() > 20  # rays that stop on the vehicle


def test_without_the_library_the_caster_falls_back_to_embreex(monkeypatch, rough_world):
    world, own = rough_world
    o, d = _lidar_rays(np.array([0.0, 0.0, 2.2]), n_azimuth=300)
    with_packets = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id]).cast(o, d, 120.0)
    monkeypatch.setattr(embree_packets, "_library_candidates", lambda: [])
    monkeypatch.setattr(embree_packets, "_LIBRARY", [])
    assert not embree_packets.packets_available()
    caster = EmbreeCaster.from_world(world, exclude_body_ids=[own.body_id])
    assert caster._static._packets is None
    np.testing.assert_array_equal(caster.cast(o, d, 120.0), with_packets)


def test_ray_packets_must_be_a_bool():
    with pytest.raises(ConfigError, match="ray_packets"):
        EmbreeConfig(ray_packets=1)


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
        with pytest.raises(ValueError, match="one per ray or one for all"):
            scene._packets.cast(o32[:2], d32, 120.0)
        with pytest.raises(ValueError, match="out"):
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
