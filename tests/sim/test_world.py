"""PyBullet world: terrain body matches ground truth, lifecycle, configs, leaks."""

from __future__ import annotations

import gc

import numpy as np
import pybullet as p
import pytest

from negobs_gym.errors import ConfigError, SimulationError
from negobs_gym.sim import presets
from negobs_gym.sim.types import HeightField, PositiveObstacle
from negobs_gym.sim.world import World, WorldConfig, physics_heightfield
from tests.helpers import rss_mb
from tests.sim.helpers import flat_terrain


def test_heightfield_sample_points_match_terrain_exactly():
    terrain = flat_terrain(20, 8, roughness_m=0.1, pits=(("p", 1.0, 8.0, 1.0, 1.0, 0.8),))
    with World(terrain) as world:
        hf = world.physics_heightfield
        ny, nx = hf.shape
        j, i = np.meshgrid(np.arange(2, ny - 2, 7), np.arange(2, nx - 2, 5), indexing="ij")
        xy = np.stack(
            [hf.origin_m[0] + i * hf.resolution_m, hf.origin_m[1] + j * hf.resolution_m], -1
        ).reshape(-1, 2)
        hit = world.ray_test_down(xy)
        expected = terrain.heightfield.height_at(xy)
    np.testing.assert_allclose(hit, expected, atol=2e-3)


@pytest.mark.parametrize("physics_resolution_m", [0.1, 0.2, 0.25, 0.3])
def test_ray_at_obstacle_centre_hits_recorded_floor(physics_resolution_m):
    terrain = presets.braking_track(
        ditch_distance_m=10.0, ditch_length_m=1.0, ditch_width_m=1.0, ditch_depth_m=0.8, seed=3
    )
    ditch = terrain.negative_obstacles[0]
    with World(terrain, WorldConfig(physics_resolution_m=physics_resolution_m)) as world:
        z = world.ray_test_down(ditch.centre_xy_m[None])[0]
    assert z == pytest.approx(ditch.floor_z_m, abs=0.02)
    rim = terrain.heightfield.height_at(ditch.centre_xy_m + np.array([0.0, -1.5]))
    assert rim - z == pytest.approx(ditch.depth_m, abs=0.15)  # rough rim: depth is to the mean rim


def test_positive_obstacle_body_is_where_the_record_says():
    box = PositiveObstacle(
        obstacle_id="rock-1",
        kind="box",
        shape="box",
        centre_m=np.array([2.0, 10.0, 0.5]),
        half_extents_m=np.array([0.5, 0.5, 0.5]),
    )
    with World(flat_terrain(20, 8, positives=(box,))) as world:
        assert set(world.obstacle_body_ids) == {"rock-1"}
        z = world.ray_test_down(np.array([[2.0, 10.0], [3.0, 10.0]]))
    assert z[0] == pytest.approx(1.0, abs=1e-3)
    assert z[1] == pytest.approx(0.0, abs=1e-3)


def test_close_is_idempotent_and_closed_world_raises():
    world = World(flat_terrain(10, 6))
    cid = world.client_id
    world.close()
    world.close()
    assert world.closed
    assert not p.isConnected(physicsClientId=cid)
    with pytest.raises(SimulationError, match="closed"):
        world.step()
    with pytest.raises(SimulationError):
        _ = world.client_id


def test_fifty_worlds_leak_no_clients_or_memory():
    terrain = flat_terrain(10, 6)
    with World(terrain):
        pass
    gc.collect()
    before = rss_mb()
    ids = []
    for _ in range(50):
        with World(terrain) as world:
            ids.append(world.client_id)
            world.step(2)
    gc.collect()
    assert not any(p.isConnected(physicsClientId=c) for c in ids)
    assert rss_mb() - before < 100.0


def test_physics_heightfield_subsamples_or_interpolates():
    h = np.arange(25, dtype=np.float32).reshape(5, 5)
    hf = HeightField(heights_m=h, resolution_m=0.1, origin_m=(1.0, 2.0))
    coarse = physics_heightfield(hf, 0.2)
    np.testing.assert_array_equal(coarse.heights_m, h[::2, ::2])
    assert coarse.resolution_m == pytest.approx(0.2)
    odd = physics_heightfield(hf, 0.15)
    assert odd.shape == (3, 3)
    assert odd.heights_m[1, 1] == pytest.approx(h[1:3, 1:3].mean() + 0.0, abs=1e-5)
    with pytest.raises(ConfigError, match="physics_resolution_m"):
        physics_heightfield(hf, 0.05)
    bad = HeightField(heights_m=np.full((3, 3), np.nan, np.float32), resolution_m=0.1, origin_m=(0.0, 0.0))
    with pytest.raises(ConfigError, match="NaN"):
        physics_heightfield(bad, 0.1)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("time_step_s", 0.0),
        ("time_step_s", float("nan")),
        ("physics_resolution_m", -0.2),
        ("terrain_friction", 0.0),
        ("terrain_friction", -1.0),
        ("gravity_mps2", 0.0),
        ("solver_iterations", 0),
        ("pybullet_renderer", 1),
    ],
)
def test_bad_world_config_names_the_field(field, value):
    with pytest.raises(ConfigError) as err:
        WorldConfig(**{field: value})
    assert err.value.field == field


def test_world_rejects_non_terrain():
    with pytest.raises(ConfigError, match="terrain"):
        World("not a terrain")  # type: ignore[arg-type]


def test_vehicle_and_monitor_on_a_closed_world_raise():
    from negobs_gym.sim.events import EventMonitor
    from negobs_gym.sim.vehicle import Vehicle

    world = World(flat_terrain(10, 6))
    vehicle = Vehicle(world)
    monitor = EventMonitor(world, vehicle)
    assert world.dynamic_body_ids() == (vehicle.body_id,)
    world.close()
    for call in (vehicle.pose, vehicle.speed_mps, monitor.poll, world.dynamic_body_ids):
        with pytest.raises(SimulationError):
            call()
    with pytest.raises(SimulationError):
        vehicle.apply(0.0, 0.0, 0.0)


def test_software_renderer_is_dropped_unless_asked_for():
    terrain = flat_terrain(10, 6)
    with World(terrain) as world:
        with pytest.raises(p.error, match="visual shape"):
            p.getVisualShapeData(world.terrain_body_id, physicsClientId=world.client_id)
    with World(terrain, WorldConfig(pybullet_renderer=True)) as world:
        shapes = p.getVisualShapeData(world.terrain_body_id, physicsClientId=world.client_id)
        assert len(shapes) == 1


def test_dropping_the_renderer_leaves_the_drive_bit_identical():
    from negobs_gym.sim.vehicle import Vehicle

    terrain = flat_terrain(30, 8, roughness_m=0.1, pits=(("p", -0.4, 8.0, 2.0, 0.6, 0.3),))
    drives = []
    for renderer in (False, True):
        with World(terrain, WorldConfig(pybullet_renderer=renderer)) as world:
            vehicle = Vehicle(world)
            vehicle.set_speed(5.0)
            poses = []
            for k in range(120):
                vehicle.apply(0.6, 0.0, 0.2 * np.sin(k / 10))
                world.step(4)
                pose = vehicle.true_pose()
                poses.append((pose.x, pose.y, pose.z, pose.roll, pose.pitch, pose.yaw, vehicle.speed_mps()))
            drives.append(np.array(poses))
    assert drives[0][-1, 1] > 10.0  # it drove over the rough ground, across the pit's row
    np.testing.assert_array_equal(drives[0], drives[1])
