"""The autonomous land vehicle: a PyBullet multibody with suspension, Ackermann steering and brakes.

Built from primitives in code: a box chassis (the base) and, per wheel, a prismatic suspension link
(spring + damper applied as joint forces every physics step), a steering link on the front wheels and
a sphere wheel (spheres ran about 4x faster than cylinders on a heightfield with the same braking
result). Wheel contact is soft (``contactStiffness`` / ``contactDamping``) so the tyres stay on the
ground; damping of the bodies is zero so nothing but tyre friction slows the car.

Vehicle frame (README, "Frames and units"): origin at the rear-axle centre on the ground, Y forward,
X right, Z up.
The PyBullet base frame has the same axes, so its rotation is the vehicle's rotation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pybullet as p

from negobs_gym.core.geometry import heading_axes
from negobs_gym.core.pose import Pose, pose_from_matrix, roll_pitch_from_bottom_row
from negobs_gym.errors import ActionError, ConfigError, require
from negobs_gym.sim.world import World

__all__ = ["Vehicle", "VehicleConfig"]

WHEEL_NAMES = ("front_left", "front_right", "rear_left", "rear_right")


@dataclass(frozen=True, kw_only=True)
class VehicleConfig:
    """Geometry, mass and actuator limits of the full-size ALV (docs/physics.md).

    Lengths in metres, masses in kg, forces in N, torques in N m, angles in degrees (config edge).
    """

    length_m: float = 4.5  # docs/physics.md: about 4.5 x 2.0 m
    width_m: float = 2.0
    body_height_m: float = 0.9  # chassis box height above the belly
    ground_clearance_m: float = 0.35  # belly height at rest
    wheelbase_m: float = 2.8  # docs/physics.md
    track_width_m: float = 1.6  # wheel centre to wheel centre, left to right
    rear_overhang_m: float = 0.85  # rear bumper behind the rear axle
    wheel_radius_m: float = 0.4
    mass_kg: float = 2000.0  # docs/physics.md: ~2000 kg, everything included
    wheel_mass_kg: float = 25.0
    cg_height_m: float = 0.6  # centre of mass above the ground at rest
    max_steer_deg: float = 35.0  # paper T: maximum steering angle 35 deg
    tyre_mu: float = 0.65  # paper N §4 / Eq. 18: tyre-ground friction coefficient
    max_drive_force_n: float = 6000.0  # total tractive force at full throttle (~0.3 g)
    drive: Literal["rear", "all"] = "rear"
    max_brake_torque_nm: float = 4000.0  # per wheel; ~3x the locking torque, so 1.0 = locked wheels
    max_steer_torque_nm: float = 5000.0
    suspension_stiffness_npm: float = 45000.0  # per wheel; ~1.5 Hz sprung natural frequency
    suspension_damping_nspm: float = 4000.0  # per wheel; damping ratio ~0.4
    suspension_travel_m: float = 0.15  # +- around the static ride height
    contact_stiffness_npm: float = 3.0e5  # soft tyre contact
    contact_damping_nspm: float = 2.0e4
    ins_position_noise_m: float = 0.0  # INS (GPS/INS, paper N) 1-sigma position noise
    ins_angle_noise_deg: float = 0.0  # INS 1-sigma roll/pitch/yaw noise

    @property
    def front_length_m(self) -> float:
        """Rear axle to front bumper [m]."""
        return self.length_m - self.rear_overhang_m

    @property
    def max_accel_mps2(self) -> float:
        """Acceleration at full throttle on the flat, the wheels' masses aside [m/s^2]."""
        return self.max_drive_force_n / self.mass_kg

    def hazard_geometry(self, g_mps2: float) -> dict[str, float]:
        """The car's fields of the safety filter's ``HazardState`` (width, wheelbase, front
        length, full lock, full throttle, and locked wheels' deceleration mu g under gravity
        ``g_mps2``, Eq. 18): what the env reports and a driver asking Eq. 18 itself assumes."""
        return {
            "vehicle_width_m": self.width_m,
            "wheelbase_m": self.wheelbase_m,
            "front_length_m": self.front_length_m,
            "max_steer_rad": self.max_steer_rad,
            "max_accel_mps2": self.max_accel_mps2,
            "max_brake_decel_mps2": self.tyre_mu * g_mps2,
        }

    def __post_init__(self) -> None:
        positive = (
            "length_m",
            "width_m",
            "body_height_m",
            "ground_clearance_m",
            "wheelbase_m",
            "track_width_m",
            "wheel_radius_m",
            "mass_kg",
            "wheel_mass_kg",
            "cg_height_m",
            "max_steer_deg",
            "tyre_mu",
            "max_drive_force_n",
            "max_brake_torque_nm",
            "max_steer_torque_nm",
            "suspension_stiffness_npm",
            "suspension_damping_nspm",
            "suspension_travel_m",
            "contact_stiffness_npm",
            "contact_damping_nspm",
        )
        for name in positive:
            value = getattr(self, name)
            require(
                isinstance(value, (int, float)) and math.isfinite(value) and value > 0,
                name,
                f"must be a finite number > 0, got {value!r}",
            )
        for name in ("rear_overhang_m", "ins_position_noise_m", "ins_angle_noise_deg"):
            value = getattr(self, name)
            require(
                isinstance(value, (int, float)) and math.isfinite(value) and value >= 0,
                name,
                f"must be a finite number >= 0, got {value!r}",
            )
        require(self.max_steer_deg < 60.0, "max_steer_deg", f"must be < 60 deg, got {self.max_steer_deg}")
        require(self.tyre_mu <= 2.0, "tyre_mu", f"must be <= 2 (rubber on ground), got {self.tyre_mu}")
        require(
            self.track_width_m < self.width_m + 2 * self.wheel_radius_m,
            "track_width_m",
            "must be narrower than the body plus the wheels",
        )
        require(
            self.rear_overhang_m + self.wheelbase_m < self.length_m,
            "wheelbase_m",
            f"wheelbase + rear overhang must be shorter than length_m = {self.length_m}",
        )
        require(
            self.wheel_mass_kg * 4 < 0.5 * self.mass_kg,
            "wheel_mass_kg",
            "four wheels must weigh less than half the vehicle",
        )
        require(self.drive in ("rear", "all"), "drive", f"must be 'rear' or 'all', got {self.drive!r}")

    @property
    def max_steer_rad(self) -> float:
        """Maximum (bicycle-model) steering angle [rad]."""
        return math.radians(self.max_steer_deg)


class Vehicle:
    """The ALV in a :class:`World`, driven by :meth:`apply` (throttle, brake, steer).

    Args:
        world: The world to build in; the vehicle registers a per-step hook there (suspension and
            drive forces).
        config: Vehicle parameters; defaults are docs/physics.md / paper values.
        start_pose: Where to put the vehicle frame origin: x, y and yaw are used; the vehicle is
            placed on the terrain (z, roll, pitch are taken from the ground).
        rng: Generator for INS noise; required when the config asks for noise.
    """

    def __init__(
        self,
        world: World,
        config: VehicleConfig | None = None,
        start_pose: Pose | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.config = config if config is not None else VehicleConfig()
        if not isinstance(self.config, VehicleConfig):
            raise ConfigError("config", f"must be a VehicleConfig, got {type(self.config).__name__}")
        noisy = self.config.ins_position_noise_m > 0 or self.config.ins_angle_noise_deg > 0
        if noisy and not isinstance(rng, np.random.Generator):
            raise ConfigError("rng", "INS noise is configured: pass an np.random.Generator as rng")
        self.world = world
        self._rng = rng
        self._throttle = 0.0
        self._brake = 0.0
        self._steer = 0.0
        cfg = self.config
        self._com_offset = np.array([0.0, 0.5 * cfg.wheelbase_m, cfg.cg_height_m])  # vehicle origin -> COM
        self._build()
        start = (
            start_pose
            if start_pose is not None
            else Pose(*world.terrain.start_xy_yaw[:2], 0.0, 0.0, 0.0, world.terrain.start_xy_yaw[2])
        )
        self.reset(start)
        world.add_dynamic_body(self.body_id)
        world.add_step_hook(self._pre_step)

    # -- construction --------------------------------------------------------------------------
    def _build(self) -> None:
        cfg = self.config
        c = self.world.client_id
        half_len, half_w, half_h = 0.5 * cfg.length_m, 0.5 * cfg.width_m, 0.5 * cfg.body_height_m
        box_centre_vehicle = np.array([0.0, half_len - cfg.rear_overhang_m, cfg.ground_clearance_m + half_h])
        chassis = p.createCollisionShape(
            p.GEOM_BOX,
            halfExtents=[half_w, half_len, half_h],
            collisionFramePosition=(box_centre_vehicle - self._com_offset).tolist(),
            physicsClientId=c,
        )
        small = p.createCollisionShape(p.GEOM_SPHERE, radius=0.01, physicsClientId=c)
        wheel = p.createCollisionShape(p.GEOM_SPHERE, radius=cfg.wheel_radius_m, physicsClientId=c)
        self._susp_mass = 10.0
        self._steer_mass = 5.0
        chassis_mass = cfg.mass_kg - 4 * (cfg.wheel_mass_kg + self._susp_mass) - 2 * self._steer_mass
        half_track = 0.5 * cfg.track_width_m
        wheel_xy = {
            "front_left": (-half_track, cfg.wheelbase_m),
            "front_right": (half_track, cfg.wheelbase_m),
            "rear_left": (-half_track, 0.0),
            "rear_right": (half_track, 0.0),
        }
        masses, shapes, parents, positions, joint_types, axes = [], [], [], [], [], []
        self.suspension_joints: list[int] = []
        self.steer_joints: list[int] = []
        self.wheel_joints: list[int] = []
        for name in WHEEL_NAMES:
            x, y = wheel_xy[name]
            mount = np.array([x, y, cfg.wheel_radius_m]) - self._com_offset
            masses.append(self._susp_mass)
            shapes.append(small)
            parents.append(0)  # base
            positions.append(mount.tolist())
            joint_types.append(p.JOINT_PRISMATIC)
            axes.append([0.0, 0.0, 1.0])
            self.suspension_joints.append(len(masses) - 1)
            parent = len(masses)  # 1-based link index of the suspension link
            if name.startswith("front"):
                masses.append(self._steer_mass)
                shapes.append(small)
                parents.append(parent)
                positions.append([0.0, 0.0, 0.0])
                joint_types.append(p.JOINT_REVOLUTE)
                axes.append([0.0, 0.0, 1.0])  # positive = steer left
                self.steer_joints.append(len(masses) - 1)
                parent = len(masses)
            masses.append(cfg.wheel_mass_kg)
            shapes.append(wheel)
            parents.append(parent)
            positions.append([0.0, 0.0, 0.0])
            joint_types.append(p.JOINT_REVOLUTE)
            axes.append([-1.0, 0.0, 0.0])  # positive = rolling forward
            self.wheel_joints.append(len(masses) - 1)
        n = len(masses)
        self.body_id = p.createMultiBody(
            baseMass=chassis_mass,
            baseCollisionShapeIndex=chassis,
            basePosition=[0.0, 0.0, 5.0],
            linkMasses=masses,
            linkCollisionShapeIndices=shapes,
            linkVisualShapeIndices=[-1] * n,
            linkPositions=positions,
            linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
            linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n,
            linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
            linkParentIndices=parents,
            linkJointTypes=joint_types,
            linkJointAxis=axes,
            physicsClientId=c,
        )
        p.changeDynamics(self.body_id, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        for link in range(n):
            p.changeDynamics(
                self.body_id, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0, physicsClientId=c
            )
        for link in self.suspension_joints:
            p.changeDynamics(
                self.body_id,
                link,
                jointLowerLimit=-cfg.suspension_travel_m,
                jointUpperLimit=cfg.suspension_travel_m,
                physicsClientId=c,
            )
        for link in self.suspension_joints + self.steer_joints:
            p.setCollisionFilterGroupMask(self.body_id, link, 0, 0, physicsClientId=c)
        for link in self.wheel_joints:
            p.changeDynamics(
                self.body_id,
                link,
                lateralFriction=cfg.tyre_mu,
                rollingFriction=0.0,
                spinningFriction=0.0,
                restitution=0.0,
                contactStiffness=cfg.contact_stiffness_npm,
                contactDamping=cfg.contact_damping_nspm,
                physicsClientId=c,
            )
        p.changeDynamics(self.body_id, -1, lateralFriction=cfg.tyre_mu, physicsClientId=c)
        # PyBullet starts every joint with a velocity motor that brakes it: switch them all off.
        p.setJointMotorControlArray(
            self.body_id, list(range(n)), p.VELOCITY_CONTROL, forces=[0.0] * n, physicsClientId=c
        )
        sprung = cfg.mass_kg - 4 * cfg.wheel_mass_kg - 2 * self._steer_mass - 4 * self._susp_mass
        self._preload_n = sprung * self.world.config.gravity_mps2 / 4.0  # static load per corner

    def use_ins_rng(self, rng: np.random.Generator | None) -> None:
        """Draw the INS noise from ``rng`` from now on (a kept world's vehicle starts a new episode)."""
        cfg = self.config
        if (cfg.ins_position_noise_m > 0 or cfg.ins_angle_noise_deg > 0) and not isinstance(
            rng, np.random.Generator
        ):
            raise ConfigError("rng", "INS noise is configured: pass an np.random.Generator as rng")
        self._rng = rng

    # -- placement -----------------------------------------------------------------------------
    def reset(self, start_pose: Pose, speed_mps: float = 0.0) -> None:
        """Put the vehicle at ``start_pose`` (x, y, yaw) on the ground, at rest or at ``speed_mps``."""
        c = self.world.client_id
        if not isinstance(start_pose, Pose):
            raise ConfigError(
                "start_pose", f"must be a negobs_gym.core.Pose, got {type(start_pose).__name__}"
            )
        cfg = self.config
        yaw = start_pose.yaw
        fwd, right = heading_axes(yaw)
        origin = np.array([start_pose.x, start_pose.y])
        corners = np.array(
            [
                origin + right * sx * 0.5 * cfg.track_width_m + fwd * sy
                for sx in (-1, 1)
                for sy in (0.0, cfg.wheelbase_m)
            ]
        )
        ground = self.world.terrain.heightfield.height_at(corners)
        if np.any(~np.isfinite(ground)):
            raise ConfigError("start_pose", f"wheels at {corners.round(2).tolist()} are outside the terrain")
        z0 = float(ground.max()) + 0.01
        rot = Pose(0.0, 0.0, 0.0, 0.0, 0.0, yaw).rotation
        com = np.array([start_pose.x, start_pose.y, z0]) + rot @ self._com_offset
        quat = p.getQuaternionFromEuler([0.0, 0.0, yaw])
        p.resetBasePositionAndOrientation(self.body_id, com.tolist(), quat, physicsClientId=c)
        for j in self.suspension_joints + self.steer_joints + self.wheel_joints:
            p.resetJointState(self.body_id, j, 0.0, 0.0, physicsClientId=c)
        self.apply(0.0, 0.0, 0.0)
        self.set_speed(speed_mps)

    def set_speed(self, speed_mps: float) -> None:
        """Set the forward speed [m/s] of the chassis and the matching wheel spin (rolling)."""
        if not math.isfinite(speed_mps):
            raise ActionError(f"speed_mps must be finite, got {speed_mps}")
        c = self.world.client_id
        _, orn = p.getBasePositionAndOrientation(self.body_id, physicsClientId=c)
        rot = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
        p.resetBaseVelocity(
            self.body_id, (rot[:, 1] * speed_mps).tolist(), [0.0, 0.0, 0.0], physicsClientId=c
        )
        spin = speed_mps / self.config.wheel_radius_m
        for j in self.wheel_joints:
            q = p.getJointState(self.body_id, j, physicsClientId=c)[0]
            p.resetJointState(self.body_id, j, q, spin, physicsClientId=c)

    # -- commands ------------------------------------------------------------------------------
    def apply(self, throttle: float, brake: float, steer: float) -> None:
        """Set the driver's commands; they hold until the next call.

        Args:
            throttle: 0..1 of ``max_drive_force_n`` on the driven wheels.
            brake: 0..1 of ``max_brake_torque_nm`` per wheel; 1 locks the wheels.
            steer: -1..1 of the maximum steering angle, +1 = full LEFT (positive yaw rate).

        Raises:
            ActionError: a command is NaN/inf or outside its range.
        """
        for name, value, lo in (("throttle", throttle, 0.0), ("brake", brake, 0.0), ("steer", steer, -1.0)):
            v = float(value)
            if not math.isfinite(v) or v < lo - 1e-9 or v > 1.0 + 1e-9:
                raise ActionError(f"{name} must be a finite number in [{lo:g}, 1], got {value!r}")
        self._throttle = min(max(float(throttle), 0.0), 1.0)
        self._brake = min(max(float(brake), 0.0), 1.0)
        self._steer = min(max(float(steer), -1.0), 1.0)
        cfg = self.config
        c = self.world.client_id
        brake_torque = self._brake * cfg.max_brake_torque_nm
        p.setJointMotorControlArray(
            self.body_id,
            self.wheel_joints,
            p.VELOCITY_CONTROL,
            targetVelocities=[0.0] * 4,
            forces=[brake_torque] * 4,
            physicsClientId=c,
        )
        left, right = self.ackermann_angles_rad(self._steer * cfg.max_steer_rad)
        p.setJointMotorControlArray(
            self.body_id,
            self.steer_joints,
            p.POSITION_CONTROL,
            targetPositions=[left, right],
            forces=[cfg.max_steer_torque_nm] * 2,
            physicsClientId=c,
        )

    def ackermann_angles_rad(self, delta_rad: float) -> tuple[float, float]:
        """(left, right) front wheel angles for a bicycle-model steering angle (Ackermann geometry)."""
        if abs(delta_rad) < 1e-9:
            return 0.0, 0.0
        cfg = self.config
        radius = cfg.wheelbase_m / math.tan(delta_rad)  # signed, > 0 turning left
        half = 0.5 * cfg.track_width_m
        return math.atan(cfg.wheelbase_m / (radius - half)), math.atan(cfg.wheelbase_m / (radius + half))

    def _pre_step(self) -> None:
        cfg = self.config
        c = self.world.client_id
        states = p.getJointStates(self.body_id, self.suspension_joints, physicsClientId=c)
        q = np.array([s[0] for s in states])
        qd = np.array([s[1] for s in states])
        # Spring + damper between body and wheel: force on the wheel link along +Z (compression q > 0).
        spring = -(self._preload_n + cfg.suspension_stiffness_npm * q + cfg.suspension_damping_nspm * qd)
        driven = self.wheel_joints if cfg.drive == "all" else self.wheel_joints[2:]
        torque = self._throttle * cfg.max_drive_force_n * cfg.wheel_radius_m / len(driven)
        p.setJointMotorControlArray(
            self.body_id,
            self.suspension_joints + driven,
            p.TORQUE_CONTROL,
            forces=[*spring.tolist(), *([torque] * len(driven))],
            physicsClientId=c,
        )

    # -- read-outs -----------------------------------------------------------------------------
    @property
    def command(self) -> tuple[float, float, float]:
        """The last (throttle, brake, steer) passed to :meth:`apply`."""
        return self._throttle, self._brake, self._steer

    def _base(self) -> tuple[np.ndarray, np.ndarray]:
        c = self.world.client_id
        pos, orn = p.getBasePositionAndOrientation(self.body_id, physicsClientId=c)
        return np.asarray(pos), np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)

    def true_pose(self) -> Pose:
        """Exact pose of the vehicle frame (rear-axle centre on the ground) in the world frame."""
        com, rot = self._base()
        return pose_from_matrix(com - rot @ self._com_offset, rot)

    def tilt_rad(self) -> float:
        """The chassis's larger tilt, max(|roll|, |pitch|) [rad] of :meth:`true_pose`, read without
        building the pose (the event checks ask at every physics sub-step)."""
        _, orn = p.getBasePositionAndOrientation(self.body_id, physicsClientId=self.world.client_id)
        r = p.getMatrixFromQuaternion(orn)
        roll, pitch = roll_pitch_from_bottom_row(r[6], r[7], r[8])
        return max(abs(roll), abs(pitch))

    def pose(self) -> Pose:
        """The INS pose: :meth:`true_pose` plus Gaussian noise when the config asks for it."""
        exact = self.true_pose()
        cfg = self.config
        if self._rng is None or (cfg.ins_position_noise_m == 0 and cfg.ins_angle_noise_deg == 0):
            return exact
        noise = self._rng.normal(size=6) * np.repeat(
            [cfg.ins_position_noise_m, math.radians(cfg.ins_angle_noise_deg)], 3
        )
        return Pose.from_array(exact.as_array() + noise)

    def speed_mps(self) -> float:
        """Signed forward speed [m/s] (along the vehicle's +Y axis)."""
        c = self.world.client_id
        lin, _ = p.getBaseVelocity(self.body_id, physicsClientId=c)
        _, rot = self._base()
        return float(np.dot(lin, rot[:, 1]))

    def yaw_rate(self) -> float:
        """Yaw rate [rad/s], positive turning left."""
        c = self.world.client_id
        _, ang = p.getBaseVelocity(self.body_id, physicsClientId=c)
        return float(ang[2])

    def steering_angle_rad(self) -> float:
        """Bicycle-model steering angle [rad] equivalent to the two front wheels' actual angles."""
        c = self.world.client_id
        left, right = (s[0] for s in p.getJointStates(self.body_id, self.steer_joints, physicsClientId=c))
        tl, tr = math.tan(left), math.tan(right)
        if tl * tr <= 0.0:
            return 0.5 * (left + right)
        return math.atan(2.0 * tl * tr / (tl + tr))  # cot(delta) = mean of the wheels' cot

    def wheel_centres(self) -> np.ndarray:
        """World positions (4, 3) of the wheel centres, order :data:`WHEEL_NAMES`."""
        c = self.world.client_id
        states = p.getLinkStates(self.body_id, self.wheel_joints, physicsClientId=c)
        return np.array([s[0] for s in states], dtype=np.float64)

    def wheel_contact_xy(self) -> np.ndarray:
        """World xy (4, 2) of each wheel's contact patch: the point under the (sphere) wheel centre."""
        return self.wheel_centres()[:, :2]

    def wheels_on_ground(self) -> np.ndarray:
        """(4,) bool: which wheels touch the terrain now."""
        c = self.world.client_id
        terrain = self.world.terrain_body_id
        return np.array(
            [
                len(p.getContactPoints(self.body_id, terrain, linkIndexA=j, physicsClientId=c)) > 0
                for j in self.wheel_joints
            ]
        )

    def chassis_on_ground(self) -> bool:
        """True while the chassis (belly or body) touches the terrain."""
        c = self.world.client_id
        return (
            len(
                p.getContactPoints(self.body_id, self.world.terrain_body_id, linkIndexA=-1, physicsClientId=c)
            )
            > 0
        )
