"""Vehicle physics: braking distance, turning radius, pose conventions, commands, configs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.core.pose import Pose
from negobs_gym.errors import ActionError, ConfigError
from negobs_gym.sim.vehicle import Vehicle, VehicleConfig
from negobs_gym.sim.world import World, WorldConfig
from tests.sim.helpers import flat_terrain

SPEED_25_KMH = 25.0 / 3.6


def brake_from(speed_mps: float, time_step_s: float = 1 / 240, mu: float = 0.65) -> float:
    """Stop distance [m] of a full brake on flat ground."""
    with World(flat_terrain(30, 8), WorldConfig(time_step_s=time_step_s)) as world:
        vehicle = Vehicle(world, VehicleConfig(tyre_mu=mu))
        world.step(round(0.5 / time_step_s))
        start = vehicle.true_pose().translation
        vehicle.set_speed(speed_mps)
        vehicle.apply(0.0, 1.0, 0.0)
        for _ in range(round(5.0 / time_step_s)):
            world.step()
            if vehicle.speed_mps() < 0.01:
                break
        return float(np.linalg.norm(vehicle.true_pose().translation[:2] - start[:2]))


@pytest.mark.parametrize("time_step_s", [1 / 240, 1 / 120])
def test_full_brake_from_25_kmh_stops_within_10_percent_of_ideal(time_step_s):
    ideal = SPEED_25_KMH**2 / (2 * 0.65 * 9.81)  # paper N Eq. 18, physics part: 3.78 m
    assert ideal == pytest.approx(3.78, abs=0.01)
    assert brake_from(SPEED_25_KMH, time_step_s) == pytest.approx(ideal, rel=0.10)


def test_braking_distance_follows_friction():
    slick = brake_from(SPEED_25_KMH, mu=0.4)
    assert slick == pytest.approx(SPEED_25_KMH**2 / (2 * 0.4 * 9.81), rel=0.10)


def test_turning_radius_at_full_lock_matches_bicycle_model():
    with World(flat_terrain(30, 24)) as world:
        vehicle = Vehicle(world)
        world.step(120)
        vehicle.set_speed(2.0)
        points = []
        for k in range(240 * 10):
            throttle = float(np.clip(0.5 * (2.0 - vehicle.speed_mps()), 0.0, 1.0))
            vehicle.apply(throttle, 0.0, 1.0)
            world.step()
            if k > 240 * 3 and k % 24 == 0:
                points.append(vehicle.true_pose().translation[:2])
        assert vehicle.yaw_rate() > 0  # steer +1 turns left
        assert vehicle.steering_angle_rad() == pytest.approx(math.radians(35), abs=math.radians(1))
    pts = np.array(points)
    a = np.column_stack([2 * pts, np.ones(len(pts))])
    cx, cy, c = np.linalg.lstsq(a, (pts**2).sum(axis=1), rcond=None)[0]
    radius = math.sqrt(c + cx**2 + cy**2)
    assert radius == pytest.approx(2.8 / math.tan(math.radians(35)), rel=0.15)
    assert cx < 0  # centre of a left turn lies to the left of the start (world -X at yaw 0)


def test_pose_frame_and_forward_motion():
    yaw = math.pi / 2  # facing world -X
    with World(flat_terrain(30, 30)) as world:
        vehicle = Vehicle(world, start_pose=Pose(x=3.0, y=10.0, yaw=yaw))
        world.step(120)
        pose = vehicle.pose()
        assert pose.yaw == pytest.approx(yaw, abs=1e-3)
        assert (pose.x, pose.y) == pytest.approx((3.0, 10.0), abs=0.05)
        assert pose.z == pytest.approx(0.0, abs=0.05)  # the origin is on the ground
        wheels = vehicle.wheel_contact_xy()
        # rear wheels straddle the origin across the heading; front wheels one wheelbase ahead
        np.testing.assert_allclose(wheels[2:].mean(axis=0), [3.0, 10.0], atol=0.05)
        np.testing.assert_allclose(wheels[:2].mean(axis=0), [3.0 - 2.8, 10.0], atol=0.05)
        assert vehicle.wheels_on_ground().all()
        assert not vehicle.chassis_on_ground()
        vehicle.set_speed(3.0)
        assert vehicle.speed_mps() == pytest.approx(3.0)
        world.step(240)
        assert vehicle.pose().x < 3.0 - 2.0
        assert vehicle.speed_mps() > 2.0


def test_throttle_accelerates_and_same_commands_give_identical_runs():
    def run() -> np.ndarray:
        with World(flat_terrain(30, 8, roughness_m=0.05, seed=1)) as world:
            vehicle = Vehicle(world)
            vehicle.apply(1.0, 0.0, 0.3)
            world.step(480)
            return np.append(vehicle.true_pose().as_array(), vehicle.speed_mps())

    a, b = run(), run()
    np.testing.assert_array_equal(a, b)
    assert a[-1] > 3.0  # ~3 m/s^2 for 2 s from rest


def test_ins_noise_needs_a_generator_and_is_reproducible():
    config = VehicleConfig(ins_position_noise_m=0.1, ins_angle_noise_deg=0.5)
    with World(flat_terrain(20, 8)) as world:
        with pytest.raises(ConfigError, match="rng"):
            Vehicle(world, config)
        noisy = [Vehicle(world, config, rng=np.random.default_rng(7)) for _ in range(2)]
        a = np.array([noisy[0].pose().as_array() for _ in range(200)])
        b = np.array([noisy[1].pose().as_array() for _ in range(200)])
        truth = noisy[0].true_pose().as_array()
    np.testing.assert_array_equal(a, b)
    assert np.std(a[:, 0] - truth[0]) == pytest.approx(0.1, rel=0.25)
    assert np.std(a[:, 5] - truth[5]) == pytest.approx(math.radians(0.5), rel=0.25)


@pytest.mark.parametrize(
    "command",
    [(float("nan"), 0, 0), (0, float("inf"), 0), (1.5, 0, 0), (0, -0.1, 0), (0, 0, 1.2), (-0.5, 0, 0)],
)
def test_bad_commands_raise_action_error(command):
    with World(flat_terrain(10, 6)) as world:
        vehicle = Vehicle(world)
        with pytest.raises(ActionError):
            vehicle.apply(*command)


def test_start_outside_terrain_is_rejected():
    with World(flat_terrain(10, 6)) as world, pytest.raises(ConfigError, match="start_pose"):
        Vehicle(world, start_pose=Pose(x=100.0, y=0.0))


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("tyre_mu", 0.0),
        ("tyre_mu", -0.65),
        ("length_m", -4.5),
        ("wheelbase_m", 0.0),
        ("wheelbase_m", 5.0),
        ("mass_kg", float("nan")),
        ("wheel_radius_m", -0.4),
        ("max_steer_deg", 0.0),
        ("max_steer_deg", 80.0),
        ("rear_overhang_m", -1.0),
        ("ins_position_noise_m", -0.1),
        ("drive", "front"),
        ("suspension_stiffness_npm", 0.0),
    ],
)
def test_bad_vehicle_config_names_the_field(field, value):
    with pytest.raises(ConfigError) as err:
        VehicleConfig(**{field: value})
    assert err.value.field == field


def test_ackermann_inner_wheel_turns_more():
    with World(flat_terrain(10, 6)) as world:
        vehicle = Vehicle(world)
        left, right = vehicle.ackermann_angles_rad(math.radians(35))
        assert left > math.radians(35) > right > 0
        cot_mean = 0.5 * (1 / math.tan(left) + 1 / math.tan(right))
        assert math.atan(1 / cot_mean) == pytest.approx(math.radians(35))


def test_tilt_is_the_larger_of_the_true_poses_roll_and_pitch_bit_for_bit():
    import pybullet as p

    with World(flat_terrain(20, 8)) as world:
        vehicle = Vehicle(world)
        vehicle.reset(Pose(0.0, 5.0, 0.0, yaw=0.3))
        c = world.client_id
        x, y, z = p.getBasePositionAndOrientation(vehicle.body_id, physicsClientId=c)[0]
        tilted = p.getQuaternionFromEuler([0.25, -0.15, 0.3])
        p.resetBasePositionAndOrientation(vehicle.body_id, [x, y, z + 0.5], tilted, physicsClientId=c)
        tilts = []
        for _ in range(60):
            world.step(4)
            pose = vehicle.true_pose()
            tilts.append(vehicle.tilt_rad())
            assert tilts[-1] == max(abs(pose.roll), abs(pose.pitch))
        assert tilts[0] > 0.1 > 0.05 > tilts[-1]  # dropped tilted, settled on the flat ground


def test_the_yaw_rate_lags_the_steering_at_25_kmh():
    """The car's yaw rate builds over tenths of a second after a steering step (the reason the
    safety filter's steering search keeps SafetyFilterConfig.steer_lead_s of travel to spare):
    half a lock from straight at 25 km/h turns at under half the kinematic rate v tan(phi) / l
    after 0.1 s and reaches it within 1 s."""
    steer = 0.5
    with World(flat_terrain(80, 40)) as world:
        vehicle = Vehicle(world)
        world.step(120)
        vehicle.set_speed(SPEED_25_KMH)
        ratios = []
        for k in range(240):
            throttle = float(np.clip(0.5 * (SPEED_25_KMH - vehicle.speed_mps()), 0.0, 1.0))
            vehicle.apply(throttle, 0.0, steer)
            world.step()
            if (k + 1) % 24 == 0:
                kinematic = vehicle.speed_mps() * math.tan(steer * math.radians(35)) / 2.8
                ratios.append(vehicle.yaw_rate() / kinematic)
    assert ratios[0] < 0.5  # 0.1 s
    assert ratios[-1] == pytest.approx(1.0, abs=0.05)  # 1.0 s
