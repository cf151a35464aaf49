"""Ground-truth events: negative-obstacle entry, trapped, collision, rollover."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from negobs_gym.core.geometry import pad_polygons, points_in_polygons
from negobs_gym.errors import ConfigError
from negobs_gym.sim import presets
from negobs_gym.sim.events import EventConfig, EventMonitor, StepEvents, _PolygonBoxes
from negobs_gym.sim.types import PositiveObstacle, Terrain
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World
from tests.sim.helpers import flat_terrain

SPEED_25_KMH = 25.0 / 3.6


def drive(
    terrain: Terrain, seconds: float, throttle: float = 0.3, speed_mps: float = SPEED_25_KMH
) -> list[StepEvents]:
    """Drive straight from ``speed_mps``, throttle held at least at ``throttle``; events polled at 10 Hz.

    Above ``throttle`` a proportional cruise control holds ``speed_mps`` (so a stuck vehicle keeps
    pushing and a free one does not speed up).
    """
    with World(terrain) as world:
        vehicle = Vehicle(world)
        monitor = EventMonitor(world, vehicle)
        world.step(120)
        monitor.reset()
        vehicle.set_speed(speed_mps)
        vehicle.apply(throttle, 0.0, 0.0)
        out = []
        for _ in range(round(seconds * 10)):
            push = (
                throttle if vehicle.speed_mps() < 0.5 * speed_mps else 2.0 * (speed_mps - vehicle.speed_mps())
            )
            vehicle.apply(float(np.clip(push, 0.0, 1.0)), 0.0, 0.0)
            world.step(24)
            out.append(monitor.poll())
        return out


def entered(events: list[StepEvents]) -> set[str]:
    return {oid for e in events for oid in e.entered_negative_obstacle}


def pit_terrain(lateral_offset_m: float) -> Terrain:
    return presets.braking_track(
        ditch_distance_m=12.0,
        ditch_length_m=1.0,
        ditch_width_m=1.0,
        ditch_depth_m=0.8,
        lateral_offset_m=lateral_offset_m,
        rough=False,
        seed=0,
    )


def test_pit_under_a_wheel_track_is_entered_and_bridged():
    terrain = pit_terrain(0.8)  # right wheels run at +0.8 m
    events = drive(terrain, 3.0)
    assert entered(events) == {terrain.negative_obstacles[0].obstacle_id}
    assert not any(e.trapped or e.rollover or e.collision for e in events)  # 25 km/h bridges 1 m


def test_pit_between_the_wheel_tracks_is_straddled():
    events = drive(pit_terrain(0.0), 3.0)
    assert entered(events) == set()
    assert not any(e.any for e in events)


def test_three_metre_trench_traps_the_vehicle():
    terrain = presets.trench_crossing(seed=0, trench_distance_m=10.0, trench_length_m=3.0, rough=False)
    events = drive(terrain, 5.0)
    assert entered(events) == {terrain.negative_obstacles[0].obstacle_id}
    trapped = [e for e in events if e.trapped]
    assert trapped
    assert trapped[0].trapped_reason in {"stuck", "belly_on_ground", "tilt"}
    assert not any(e.rollover for e in events)


def test_rough_track_200_m_reports_nothing():
    # ~3 s on one core: fast enough for the default run
    terrain = presets.rough_track(length_m=200.0, seed=2)
    assert terrain.track.length_m == pytest.approx(200.0)
    events = drive(terrain, (terrain.track.length_m - 5.0) / SPEED_25_KMH)
    assert not any(e.entered_negative_obstacle or e.trapped or e.rollover for e in events)


def test_collision_with_a_positive_obstacle_is_reported():
    rock = PositiveObstacle(
        obstacle_id="rock-7",
        kind="rock",
        shape="box",
        centre_m=np.array([0.0, 12.0, 0.5]),
        half_extents_m=np.array([0.6, 0.3, 0.5]),
    )
    events = drive(flat_terrain(30, 8, positives=(rock,)), 2.5, speed_mps=4.0)
    assert {oid for e in events for oid in e.collision} == {"rock-7"}


def test_rollover_and_stuck_on_flat_ground():
    with World(flat_terrain(20, 10)) as world:
        vehicle = Vehicle(world)
        monitor = EventMonitor(world, vehicle)
        world.step(240)
        assert not monitor.poll().any
        vehicle.apply(0.3, 1.0, 0.0)  # throttle against a locked brake: not moving
        world.step(round(2.2 * 240))
        stuck = monitor.poll()
        assert stuck.trapped and stuck.trapped_reason == "stuck"
        pos, _ = p.getBasePositionAndOrientation(vehicle.body_id, physicsClientId=world.client_id)
        quat = p.getQuaternionFromEuler([0.0, math.radians(100), 0.0])  # on its side
        p.resetBasePositionAndOrientation(
            vehicle.body_id, [pos[0], pos[1], 2.0], quat, physicsClientId=world.client_id
        )
        world.step(1)
        assert monitor.poll().rollover


def test_monitor_checks_every_physics_step_not_only_at_poll():
    # a 0.3 m wide pit crossed at 25 km/h between two 10 Hz polls is still reported
    terrain = flat_terrain(30, 8, pits=(("narrow", 0.8, 10.0, 0.6, 0.3, 0.5),))
    assert entered(drive(terrain, 2.5)) == {"narrow"}


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("stuck_speed_mps", 0.0),
        ("stuck_time_s", -1.0),
        ("stuck_throttle", 1.5),
        ("belly_time_s", float("nan")),
        ("rollover_tilt_deg", 95.0),
        ("trapped_tilt_deg", 70.0),
    ],
)
def test_bad_event_config_names_the_field(field, value):
    with pytest.raises(ConfigError) as err:
        EventConfig(**{field: value})
    assert err.value.field == field


def test_the_box_prefilter_keeps_every_polygon_that_holds_a_wheel():
    """The polygons the monitor tests exactly include each one a wheel is in, and few others."""
    rng = np.random.default_rng(3)
    polygons = pad_polygons(
        [c + rng.uniform(-1.5, 1.5, (int(rng.integers(3, 7)), 2)) for c in rng.uniform(0.0, 40.0, (30, 2))]
    )
    boxes = _PolygonBoxes(polygons)
    inside_some = 0
    for _ in range(300):
        wheels = rng.uniform(0.0, 40.0, 2) + rng.uniform(-1.5, 1.5, (4, 2))
        holding = np.flatnonzero(points_in_polygons(wheels, polygons).any(axis=0))
        near = boxes.near(wheels)
        assert set(holding) <= set(near) and len(near) <= 12
        assert np.all(np.diff(near) > 0)
        inside_some += int(holding.size > 0)
    assert inside_some >= 10  # the superset check is not vacuous
    assert _PolygonBoxes(np.zeros((0, 3, 2))).near(np.zeros((4, 2))).size == 0
