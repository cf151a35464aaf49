"""Tiny physics-free envs implementing only the hazard protocol (no negobs internals)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from negobs_gym.safety import HazardState

DT_S = 0.1
MAX_ACCEL = 3.0
MAX_BRAKE = 0.65 * 9.81
DITCH_Y_M = 30.0


class PointCarDitchEnv(gym.Env):
    """1-D point car on a straight track; a ditch line across the track at y = 30 m.

    Its "sensor" sees the ditch every step until ``sensor_dies_at_s`` (never by default); after
    that ``hazard_state`` keeps reporting the last frame, with its old timestamp.
    """

    def __init__(self, sensor_dies_at_s: float | None = None) -> None:
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (2,), np.float64)
        self.sensor_dies_at_s = sensor_dies_at_s
        self.y = 0.0
        self.v = 0.0
        self.t = 0.0
        self._sensed = (0.0, 0.0)  # (time, y) of the last sensor frame

    def _obs(self) -> np.ndarray:
        return np.array([self.y, self.v])

    def _info(self) -> dict[str, Any]:
        return {"speed_mps": self.v, "pose": np.array([0.0, self.y, 0, 0, 0, 0.0])}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.y, self.v, self.t = 0.0, 0.0, 0.0
        self._sensed = (0.0, 0.0)
        return self._obs(), self._info()

    def step(self, action):
        a0 = float(np.clip(action[0], -1, 1))
        accel = a0 * MAX_ACCEL if a0 >= 0 else a0 * MAX_BRAKE
        v_next = max(0.0, self.v + DT_S * accel)
        self.y += 0.5 * DT_S * (self.v + v_next)
        self.v = v_next
        self.t += DT_S
        if self.sensor_dies_at_s is None or self.t < self.sensor_dies_at_s:
            self._sensed = (self.t, self.y)
        return self._obs(), 0.0, self.y >= DITCH_Y_M, False, self._info()

    def hazard_state(self) -> HazardState:
        xs = np.linspace(-2.0, 2.0, 21)
        sensed_t, sensed_y = self._sensed
        pts = np.column_stack([xs, np.full_like(xs, DITCH_Y_M - sensed_y)])
        return HazardState(
            speed_mps=self.v,
            negative_obstacles_xy_m=pts,
            vehicle_width_m=1.8,
            wheelbase_m=2.8,
            max_steer_rad=float(np.deg2rad(35)),
            dt_s=DT_S,
            max_accel_mps2=MAX_ACCEL,
            max_brake_decel_mps2=MAX_BRAKE,
            time_s=self.t,
            perception_time_s=sensed_t,
        )


class FixedHazardEnv(gym.Env):
    """Returns a preset HazardState; step records the action it received."""

    def __init__(self, state: HazardState) -> None:
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.state = state
        self.received = None

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.received = action
        return np.zeros(1, np.float32), 0.0, False, False, {}

    def hazard_state(self) -> HazardState:
        return self.state
