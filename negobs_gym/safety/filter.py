"""BrakingSafetyFilter: vetoes actions that would leave the vehicle unable to stop (Eq. 18)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Literal, SupportsFloat

import gymnasium as gym
import numpy as np

from negobs_gym.errors import ActionError, require
from negobs_gym.safety.braking import BrakingConfig, braking_distance_m, max_safe_speed_mps
from negobs_gym.safety.corridor import hazard_distance_m
from negobs_gym.safety.protocol import HazardSource, HazardState

logger = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class SafetyFilterConfig:
    """Settings of :class:`BrakingSafetyFilter` (Eq. 18 constants plus the corridor margin)."""

    braking: BrakingConfig = field(default_factory=BrakingConfig)
    margin_m: float = 0.4  # added to the vehicle width for the corridor (engineering choice) [m]
    mode: Literal["brake", "cap_speed"] = "brake"

    def __post_init__(self) -> None:
        require(
            np.isfinite(self.margin_m) and self.margin_m >= 0,
            "margin_m",
            f"must be finite and >= 0, got {self.margin_m!r}",
        )
        require(
            self.mode in ("brake", "cap_speed"), "mode", f"must be 'brake' or 'cap_speed', got {self.mode!r}"
        )


class BrakingSafetyFilter(gym.Wrapper):
    """Replaces unsafe longitudinal commands so that d - travelled >= R(v') holds after each step.

    Each step it reads ``hazard_state()`` from the env (see :mod:`negobs_gym.safety.protocol`),
    computes the hazard distance d along the arc of the *proposed* steering, predicts the speed v'
    the action leaves after one control period and the distance travelled meanwhile, and vetoes the
    action when ``d - travelled < R(v')``. ``mode="brake"`` replaces ``action[0]`` by -1;
    ``mode="cap_speed"`` uses the largest command whose v' is safe, else -1. Steering is never
    changed; safe actions pass bit-identical.

    ``info["safety"]``: vetoed, hazard_distance_m, braking_distance_m (R(v) at the current speed),
    safe_speed_mps (largest v with R(v) <= d), original_action, applied_action.
    ``info["cost"]``: 1.0 when the action was vetoed or the vehicle already violates d < R(v)
    at the decision time, else 0.0 (a constraint cost for safe RL).
    """

    def __init__(
        self,
        env: gym.Env,
        mu: float = 0.65,
        reaction_time_s: float = 0.25,
        buffer_m: float = 5.0,
        g: float = 9.81,
        margin_m: float = 0.4,
        mode: Literal["brake", "cap_speed"] = "brake",
    ) -> None:
        super().__init__(env)
        if not isinstance(env.unwrapped, HazardSource) and not isinstance(env, HazardSource):
            raise TypeError(
                f"BrakingSafetyFilter needs an env implementing hazard_state() -> HazardState "
                f"(see negobs_gym.safety.protocol); {type(env.unwrapped).__name__} has no hazard_state"
            )
        space = env.action_space
        if not (isinstance(space, gym.spaces.Box) and space.shape == (2,)):
            raise TypeError(f"BrakingSafetyFilter needs a Box action space of shape (2,), got {space}")
        self.config = SafetyFilterConfig(
            braking=BrakingConfig(mu=mu, reaction_time_s=reaction_time_s, buffer_m=buffer_m, g_mps2=g),
            margin_m=margin_m,
            mode=mode,
        )
        self.last_safety: dict[str, Any] | None = None

    def _hazard_state(self) -> HazardState:
        source = self.env.unwrapped if isinstance(self.env.unwrapped, HazardSource) else self.env
        state = source.hazard_state()
        if not isinstance(state, HazardState):
            raise TypeError(f"hazard_state() must return a HazardState, got {type(state).__name__}")
        return state

    def _r(self, v: Any) -> np.ndarray:
        b = self.config.braking
        return braking_distance_m(v, b.mu, b.reaction_time_s, b.buffer_m, b.g_mps2)

    def _is_safe(self, state: HazardState, d: float, longitudinal: float) -> bool:
        v_next = state.predicted_speed_mps(longitudinal)
        return bool(d - state.travelled_m(v_next) >= self._r(v_next))

    def _capped_longitudinal(self, state: HazardState, d: float, proposed: float) -> float:
        """Largest command <= ``proposed`` whose predicted v' satisfies d - travelled >= R(v')."""
        b = self.config.braking
        a = 1.0 / (2.0 * b.mu * b.g_mps2)
        lin = b.reaction_time_s + 0.5 * state.dt_s
        const = b.buffer_m + 0.5 * state.dt_s * state.speed_mps - d
        disc = lin * lin - 4.0 * a * const
        if disc < 0:
            return -1.0
        v_max = (-lin + np.sqrt(disc)) / (2.0 * a)
        dv = v_max - state.speed_mps
        scale = state.max_accel_mps2 if dv >= 0 else state.max_brake_decel_mps2
        cmd = float(np.clip(dv / (state.dt_s * scale), -1.0, proposed))
        for _ in range(60):  # guard against round-off: step down until the check holds
            if self._is_safe(state, d, cmd) or cmd <= -1.0:
                break
            cmd = max(-1.0, cmd - 1e-9 - 1e-6 * abs(cmd))
        return cmd if self._is_safe(state, d, cmd) else -1.0

    def filter_action(self, action: Any) -> tuple[np.ndarray, dict[str, Any]]:
        """The action to apply and the safety record, without stepping the env."""
        try:
            original = np.asarray(action, dtype=np.float32)
        except (TypeError, ValueError) as exc:
            raise ActionError(f"action must be a numeric array of shape (2,), got {action!r}") from exc
        if original.shape != (2,):
            raise ActionError(f"action must have shape (2,), got {original.shape}")
        if not np.all(np.isfinite(original)):
            raise ActionError(f"action must be finite, got {original.tolist()}")
        state = self._hazard_state()
        steer = float(np.clip(original[1], -1.0, 1.0)) * state.max_steer_rad
        half_width = 0.5 * (state.vehicle_width_m + self.config.margin_m)
        d = hazard_distance_m(state.negative_obstacles_xy_m, steer, state.wheelbase_m, half_width)
        b = self.config.braking
        r_now = float(self._r(state.speed_mps))
        proposed = float(np.clip(original[0], -1.0, 1.0))
        vetoed = not self._is_safe(state, d, proposed)
        applied = original
        if vetoed:
            if self.config.mode == "cap_speed":
                cmd = self._capped_longitudinal(state, d, proposed)
            else:
                cmd = -1.0
            applied = original.copy()
            applied[0] = np.float32(cmd)
            logger.debug("veto: d=%.2f m, v=%.2f m/s, a0 %.3f -> %.3f", d, state.speed_mps, proposed, cmd)
        record = {
            "vetoed": vetoed,
            "hazard_distance_m": d,
            "braking_distance_m": r_now,
            "safe_speed_mps": float(max_safe_speed_mps(d, b.mu, b.reaction_time_s, b.buffer_m, b.g_mps2)),
            "original_action": original.copy(),
            "applied_action": applied.copy(),
        }
        return (action if not vetoed else applied), record

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Filter ``action``, step the env, and add ``info["safety"]`` and ``info["cost"]``."""
        applied, record = self.filter_action(action)
        if hasattr(self.env.unwrapped, "set_render_overlay"):  # negobs envs draw the decision
            self.env.unwrapped.set_render_overlay(record)
        obs, reward, terminated, truncated, info = self.env.step(applied)
        info = dict(info)
        info["safety"] = record
        info["cost"] = (
            1.0 if (record["vetoed"] or record["hazard_distance_m"] < record["braking_distance_m"]) else 0.0
        )
        self.last_safety = record
        return obs, reward, terminated, truncated, info
