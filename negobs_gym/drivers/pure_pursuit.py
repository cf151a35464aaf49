"""Pure-pursuit path follower along a route of world xy points."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from negobs_gym.core.geometry import world_to_vehicle_xy
from negobs_gym.drivers.base import read_speed_mps, speed_command
from negobs_gym.errors import ActionError, ConfigError, require


@dataclass(frozen=True, kw_only=True)
class PurePursuitConfig:
    """Geometry and gains of the pure-pursuit driver."""

    lookahead_m: float = 4.0  # look-ahead distance L_d [m]
    wheelbase_m: float = 2.8  # vehicle wheelbase l [m]
    max_steer_rad: float = float(np.deg2rad(35.0))  # steering at action[1] = +1 [rad]
    target_speed_mps: float = 15.0 / 3.6  # cruise speed [m/s]
    gain_per_mps: float = 0.5  # longitudinal command per m/s of speed error [1/(m/s)]
    closed: bool = False  # the route is a loop

    def __post_init__(self) -> None:
        for name in ("lookahead_m", "wheelbase_m", "max_steer_rad", "gain_per_mps"):
            value = getattr(self, name)
            require(np.isfinite(value) and value > 0, name, f"must be finite and > 0, got {value!r}")
        require(self.max_steer_rad < np.pi / 2, "max_steer_rad", "must be < pi/2")
        require(
            np.isfinite(self.target_speed_mps) and self.target_speed_mps >= 0,
            "target_speed_mps",
            "must be finite and >= 0",
        )


class PurePursuitDriver:
    """Steers towards the route point ``lookahead_m`` ahead: curvature 2 * x_left / L_d^2.

    Reads ``info["pose"]`` (x, y, z, roll, pitch, yaw) and ``info["speed_mps"]``. Progress along the
    route only moves forward (the search starts at the last nearest index), so loops and S-bends
    that pass near themselves are followed in order.
    """

    def __init__(self, route_xy_m: np.ndarray, config: PurePursuitConfig | None = None) -> None:
        route = np.asarray(route_xy_m, dtype=float)
        if route.ndim != 2 or route.shape[1] != 2 or route.shape[0] < 2:
            raise ConfigError("route_xy_m", f"must have shape (N >= 2, 2), got {route.shape}")
        if not np.all(np.isfinite(route)):
            raise ConfigError("route_xy_m", "must be finite")
        self.route_xy_m = route
        self.config = config or PurePursuitConfig()
        self._index = 0

    def reset(self, seed: int | None = None) -> None:
        """Restart progress at the beginning of the route."""
        self._index = 0

    def _window(self) -> np.ndarray:
        n = len(self.route_xy_m)
        idx = self._index + np.arange(n)
        return np.mod(idx, n) if self.config.closed else idx[idx < n]

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """``[P(target - speed), steer]`` towards the look-ahead point."""
        if "pose" not in info:
            raise ActionError("PurePursuitDriver needs info['pose'] = (x, y, z, roll, pitch, yaw)")
        pose = np.asarray(info["pose"], dtype=float)
        if pose.shape != (6,) or not np.all(np.isfinite(pose)):
            raise ActionError(f"info['pose'] must be 6 finite numbers, got {pose}")
        xy, yaw = pose[:2], pose[5]
        window = self._window()
        pts = self.route_xy_m[window]
        dist = np.hypot(*(pts - xy).T)
        horizon = min(len(window), 200)  # nearest point searched a bounded stretch ahead
        nearest = int(np.argmin(dist[:horizon]))
        self._index = int(window[nearest])
        ahead = np.nonzero(dist[nearest:] >= self.config.lookahead_m)[0]
        target = pts[nearest + ahead[0]] if ahead.size else pts[-1]
        x_v, y_v = world_to_vehicle_xy(target, xy, yaw)  # X right, Y forward
        ld2 = max(x_v * x_v + y_v * y_v, 1e-6)
        curvature = 2.0 * (-x_v) / ld2  # left (towards -X) positive
        steer = math.atan(self.config.wheelbase_m * curvature)
        cmd = speed_command(read_speed_mps(info), self.config.target_speed_mps, self.config.gain_per_mps)
        return np.array([cmd, np.clip(steer / self.config.max_steer_rad, -1.0, 1.0)], dtype=np.float32)
