"""BrakingSafetyFilter: vetoes actions that would leave the vehicle unable to stop (Eq. 18)."""

from __future__ import annotations

import dataclasses
import logging
import math
from typing import Any, Literal, SupportsFloat

import gymnasium as gym
import numpy as np

from negobs_gym.errors import ActionError, ConfigError, InterfaceError
from negobs_gym.safety.braking import BrakingConfig, braking_distance_m, max_safe_speed_mps
from negobs_gym.safety.config import SafetyFilterConfig
from negobs_gym.safety.corridor import Corridor
from negobs_gym.safety.coverage import ClearDistance, CoverageMemory, observed_clear_distance
from negobs_gym.safety.decision import SafetyDecision
from negobs_gym.safety.memory import HazardMemory
from negobs_gym.safety.protocol import DecisionSink, HazardSource, HazardState
from negobs_gym.safety.steering import check_steering, nearest_clear_steering, passes_eq18

logger = logging.getLogger(__name__)


class BrakingSafetyFilter(gym.Wrapper):
    """Replaces unsafe longitudinal commands so that d - travelled >= R(v') holds after each step.

    Each step it reads ``hazard_state()`` from the env (see :mod:`negobs_gym.safety.protocol`),
    computes the hazard distance d along the arc of the *proposed* steering (to the nearest
    detected negative-obstacle cell; with ``stop_for_positive`` also positive-obstacle cells),
    predicts the speed v' the action leaves after one control period and the distance travelled
    meanwhile, and vetoes the action when ``d - travelled < R(v')``; after a veto, until an action
    passes again, the test is ``d - travelled < R(v') + release_margin_m`` (hysteresis against
    stop-and-go at the boundary; cleared by ``reset``). ``mode="brake"`` replaces ``action[0]`` by -1;
    ``mode="cap_speed"`` uses the largest command whose v' is safe, else -1. Steering is not
    changed unless ``steer_search`` > 0: then an action that passes the check but would fail it
    with ``steer_lead_s`` of travel to spare gets the nearest steering within that change whose
    corridor passes with that lead (``reason="steered"``, no veto); an action that fails the check
    itself is vetoed as without the search. Safe actions pass bit-identical.

    Fail-safe: when the env has no perception yet, or its hazard data is older than
    ``config.perception_timeout_s`` (``HazardState.perception_time_s`` against ``time_s``) beyond
    the age the env says its frames reach between two of them (``max_perception_age_s``, read
    once here; 0 when absent), the filter commands full brake whatever the distance.

    ``mode="governed"`` adds the speed governor (docs/safety.md): from the env's coverage
    (``HazardState.observed``, remembered for ``coverage_memory_s`` with the INS pose) it measures
    the observed clear distance c along the same corridor (:mod:`negobs_gym.safety.coverage`)
    and caps the command so that the predicted speed v' stays at or below the speed limit
    ``max(largest v' with c - travelled >= R(v') + governor_margin_m, creep)``, where the creep
    is ``creep_speed_mps`` or less, so that stopping from it leaves the front bumper
    ``creep_clearance_m`` short of the clear distance's end; it brakes fully where even that
    cannot be reached in one step. Eq. 18's veto and the stale-data
    brake apply as in ``brake`` mode and come first. An env without coverage (``observed`` None)
    counts every grid cell as observed; without a grid the governor has no range to cap against
    and only Eq. 18 applies.

    ``hazard_memory=True`` (any mode) keeps the negative-obstacle points read in the world frame
    of the INS pose until their cell is observed clear again, beyond ``hazard_memory_hold_m`` of
    the rear axle (:mod:`negobs_gym.safety.memory`).

    Settings come as ``config=SafetyFilterConfig(...)`` or, as a convenience, as keywords
    (``mu``, ``reaction_time_s``, ``buffer_m``, ``g``, ``margin_m``, ``mode``,
    ``perception_timeout_s``, ``release_margin_m``, ``stop_for_positive``, ``governor_margin_m``,
    ``creep_speed_mps``, ``creep_clearance_m``, ``unobserved_blocks``, ``coverage_memory_s``,
    ``hazard_memory``, ``hazard_memory_hold_m``, ``steer_search``, ``steer_search_step``,
    ``steer_lead_s``) over the defaults;
    passing both is a :class:`ConfigError`.

    ``info["safety"]``: :meth:`SafetyDecision.as_dict` (vetoed, hazard_distance_m,
    braking_distance_m (R(v) at the current speed), speed_mps (that speed, forward, >= 0),
    safe_speed_mps (largest v with R(v) <= d),
    original_action, applied_action, perception_age_s, perception_stale, hazard_channel,
    corridor: the :class:`~negobs_gym.safety.Corridor` searched, a frozen value; reason:
    ``"hazard"``, ``"stale_data"``, ``"unobserved"``, ``"governor"``, ``"steered"`` or None;
    governed, steered, clear_distance_m, clear_end, speed_limit_mps: the governor's cap, see
    :class:`~negobs_gym.safety.SafetyDecision`).
    ``info["cost"]``: 1.0 when the action was vetoed or the vehicle already violates d < R(v)
    at the decision time, else 0.0 (a constraint cost for safe RL). The typed record of the last
    step is :attr:`last_decision`; an env implementing :class:`DecisionSink` receives it before
    the step so its frames can show it.
    """

    def __init__(
        self,
        env: gym.Env,
        config: SafetyFilterConfig | None = None,
        *,
        mu: float | None = None,
        reaction_time_s: float | None = None,
        buffer_m: float | None = None,
        g: float | None = None,
        margin_m: float | None = None,
        mode: Literal["brake", "cap_speed", "governed"] | None = None,
        perception_timeout_s: float | None = None,
        release_margin_m: float | None = None,
        stop_for_positive: bool | None = None,
        governor_margin_m: float | None = None,
        creep_speed_mps: float | None = None,
        creep_clearance_m: float | None = None,
        unobserved_blocks: bool | None = None,
        coverage_memory_s: float | None = None,
        hazard_memory: bool | None = None,
        hazard_memory_hold_m: float | None = None,
        steer_search: float | None = None,
        steer_search_step: float | None = None,
        steer_lead_s: float | None = None,
    ) -> None:
        super().__init__(env)
        if not isinstance(env.unwrapped, HazardSource) and not isinstance(env, HazardSource):
            raise InterfaceError(
                f"BrakingSafetyFilter needs an env implementing hazard_state() -> HazardState "
                f"(see negobs_gym.safety.protocol); {type(env.unwrapped).__name__} has no hazard_state"
            )
        space = env.action_space
        if not (isinstance(space, gym.spaces.Box) and space.shape == (2,)):
            raise InterfaceError(f"BrakingSafetyFilter needs a Box action space of shape (2,), got {space}")
        braking_kw = {"mu": mu, "reaction_time_s": reaction_time_s, "buffer_m": buffer_m, "g_mps2": g}
        braking_kw = {k: v for k, v in braking_kw.items() if v is not None}
        filter_kw = {
            "margin_m": margin_m,
            "mode": mode,
            "perception_timeout_s": perception_timeout_s,
            "release_margin_m": release_margin_m,
            "stop_for_positive": stop_for_positive,
            "governor_margin_m": governor_margin_m,
            "creep_speed_mps": creep_speed_mps,
            "creep_clearance_m": creep_clearance_m,
            "unobserved_blocks": unobserved_blocks,
            "coverage_memory_s": coverage_memory_s,
            "hazard_memory": hazard_memory,
            "hazard_memory_hold_m": hazard_memory_hold_m,
            "steer_search": steer_search,
            "steer_search_step": steer_search_step,
            "steer_lead_s": steer_lead_s,
        }
        filter_kw = {k: v for k, v in filter_kw.items() if v is not None}
        if config is not None:
            if braking_kw or filter_kw:
                names = ", ".join(sorted({*braking_kw, *filter_kw}))
                raise ConfigError("config", f"pass either config or keyword settings, not both (got {names})")
            if not isinstance(config, SafetyFilterConfig):
                raise ConfigError("config", f"must be a SafetyFilterConfig, got {type(config).__name__}")
            self.config = config
        else:
            self.config = SafetyFilterConfig(braking=BrakingConfig(**braking_kw), **filter_kw)
        frame_age = getattr(env.unwrapped, "max_perception_age_s", 0.0)
        if not (isinstance(frame_age, (int, float)) and math.isfinite(frame_age) and frame_age >= 0):
            raise InterfaceError(f"max_perception_age_s must be finite and >= 0 [s], got {frame_age!r}")
        #: the env's hazards age this much between two frames in normal running (scan_every > 1)
        self.frame_age_s = float(frame_age)
        self.last_decision: SafetyDecision | None = None
        self._holding = False  # the last decision was a veto: the release margin applies
        self._coverage = CoverageMemory(self.config.coverage_memory_s)  # governed mode only
        self._hazards = HazardMemory(self.config.hazard_memory_hold_m)  # with config.hazard_memory only

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env and the filter's hysteresis."""
        self._holding = False
        self.last_decision = None
        self._coverage.reset()
        self._hazards.reset()
        return self.env.reset(seed=seed, options=options)

    def _hazard_state(self) -> HazardState:
        source = self.env.unwrapped if isinstance(self.env.unwrapped, HazardSource) else self.env
        state = source.hazard_state()
        if not isinstance(state, HazardState):
            raise InterfaceError(f"hazard_state() must return a HazardState, got {type(state).__name__}")
        if self.config.hazard_memory:
            if state.pose is None or state.grid is None:
                raise InterfaceError("hazard_memory needs a HazardState with pose and grid")
            remembered = self._hazards.update(
                state.negative_obstacles_xy_m, state.pose, state.grid, state.observed
            )
            state = dataclasses.replace(state, negative_obstacles_xy_m=remembered)
        return state

    def _r(self, v: Any) -> np.ndarray:
        return braking_distance_m(v, self.config.braking)

    def _is_safe(self, state: HazardState, d: float, longitudinal: float, lead_s: float = 0.0) -> bool:
        """Eq. 18 after one control period (plus the release margin while holding), with
        ``lead_s`` of travel at v' more to spare."""
        return passes_eq18(state, self.config, d, longitudinal, holding=self._holding, lead_s=lead_s)

    def _fitting_speed(
        self, state: HazardState, d: float, margin: float, buffer_m: float | None = None
    ) -> float | None:
        """Largest v' with d - travelled(v') >= R(v') + margin (None: not even v' = 0); R with
        ``buffer_m`` in place of Eq. 18's B where given."""
        b = self.config.braking
        a = 1.0 / (2.0 * b.mu * b.g_mps2)
        lin = b.reaction_time_s + 0.5 * state.dt_s
        buffer = b.buffer_m if buffer_m is None else buffer_m
        const = buffer + margin + 0.5 * state.dt_s * state.speed_mps - d
        disc = lin * lin - 4.0 * a * const
        if disc < 0:
            return None
        v_max = float((-lin + np.sqrt(disc)) / (2.0 * a))
        return v_max if v_max >= 0 else None

    def _capped_longitudinal(self, state: HazardState, d: float, proposed: float) -> float:
        """Largest command <= ``proposed`` whose predicted v' satisfies d - travelled >= R(v')
        (plus the release margin while holding)."""
        margin = self.config.release_margin_m if self._holding else 0.0
        v_max = self._fitting_speed(state, d, margin)
        if v_max is None:
            return -1.0
        dv = v_max - state.speed_mps
        scale = state.max_accel_mps2 if dv >= 0 else state.max_brake_decel_mps2
        cmd = float(np.clip(dv / (state.dt_s * scale), -1.0, proposed))
        for _ in range(60):  # guard against round-off: step down until the check holds
            if self._is_safe(state, d, cmd) or cmd <= -1.0:
                break
            cmd = max(-1.0, cmd - 1e-9 - 1e-6 * abs(cmd))
        return cmd if self._is_safe(state, d, cmd) else -1.0

    def _clear_distance(self, state: HazardState, corridor: Corridor) -> ClearDistance | None:
        """The observed clear distance along ``corridor`` (None: the env reports no grid)."""
        if state.grid is None:
            return None
        observed = state.observed
        if observed is not None and state.pose is not None and state.perception_time_s is not None:
            self._coverage.add(state.perception_time_s, state.pose, observed)
            near = np.isfinite(corridor.arcs_m(state.grid.cell_centres().reshape(-1, 2)))
            observed = self._coverage.observed(
                state.grid, state.pose, state.perception_time_s, cells=near.reshape(state.grid.shape)
            )
        hazards = state.negative_obstacles_xy_m
        if self.config.stop_for_positive:
            hazards = np.concatenate([hazards, state.positive_obstacles_xy_m])
        return observed_clear_distance(
            corridor, state.grid, observed, hazards, unobserved_blocks=self.config.unobserved_blocks
        )

    def _speed_limit_mps(self, state: HazardState, clear_m: float) -> float:
        """The governor's limit on v': R(v') + margin fits the clear distance, or a creep whose
        stop leaves the bumper ``creep_clearance_m`` short of its end (the larger of the two)."""
        c = self.config
        fit = self._fitting_speed(state, clear_m, c.governor_margin_m)
        nose = self._fitting_speed(state, clear_m, 0.0, state.front_length_m + c.creep_clearance_m)
        creep = min(c.creep_speed_mps, nose) if nose is not None else 0.0
        return max(fit if fit is not None else 0.0, creep)

    @staticmethod
    def _command_for(state: HazardState, v_target: float, proposed: float) -> np.float32:
        """Largest float32 command <= ``proposed`` whose predicted v' is <= ``v_target`` (-1 when
        even full braking leaves more, or the target is a stop: the car holds still on a slope,
        which the one-step model does not see)."""
        if v_target <= 0.0:
            return np.float32(-1.0)
        dv = v_target - state.speed_mps
        scale = state.max_accel_mps2 if dv >= 0 else state.max_brake_decel_mps2
        cmd = np.float32(np.clip(dv / (state.dt_s * scale), -1.0, proposed))
        while cmd > -1.0 and state.predicted_speed_mps(float(cmd)) > v_target:  # float32 round-off
            cmd = np.nextafter(cmd, np.float32(-1.0))
        return cmd

    def filter_action(self, action: Any) -> tuple[np.ndarray, SafetyDecision]:
        """The action to apply and the decision, without stepping the env (and without moving the
        hysteresis: :meth:`step` commits the decision)."""
        try:
            original = np.asarray(action, dtype=np.float32)
        except (TypeError, ValueError) as exc:
            raise ActionError(f"action must be a numeric array of shape (2,), got {action!r}") from exc
        if original.shape != (2,):
            raise ActionError(f"action must have shape (2,), got {original.shape}")
        if not np.all(np.isfinite(original)):
            raise ActionError(f"action must be finite, got {original.tolist()}")
        state = self._hazard_state()
        steer = float(np.clip(original[1], -1.0, 1.0))
        check = check_steering(state, self.config, steer)
        corridor, d, channel = check.corridor, check.hazard_distance_m, check.channel
        proposed = float(np.clip(original[0], -1.0, 1.0))
        age = state.perception_age_s
        stale = not age <= self.config.perception_timeout_s + self.frame_age_s
        vetoed = stale or not self._is_safe(state, d, proposed)
        reason = ("stale_data" if stale else "hazard") if vetoed else None
        applied = original
        steered = False
        searching = not vetoed and self.config.steer_search > 0
        if searching and not self._is_safe(state, d, proposed, self.config.steer_lead_s):
            found = nearest_clear_steering(
                state,
                self.config,
                steer,
                proposed,
                search=self.config.steer_search,
                lead_s=self.config.steer_lead_s,
                holding=self._holding,
            )
            if found is not None:
                steer, corridor, channel = found.steer, found.corridor, found.channel
                d = found.hazard_distance_m
                steered, reason = True, "steered"
                applied = original.copy()
                applied[1] = steer  # a float32 value: the corridor was searched for this command
        if vetoed:
            if self.config.mode == "cap_speed" and not stale:
                cmd = self._capped_longitudinal(state, d, proposed)
            else:
                cmd = -1.0
            applied = original.copy()
            applied[0] = np.float32(cmd)
            logger.debug(
                "veto: d=%.2f m, v=%.2f m/s, perception age %.3f s, a0 %.3f -> %.3f",
                d,
                state.speed_mps,
                age,
                proposed,
                cmd,
            )
        clear, limit, governed = None, float("inf"), False
        if self.config.mode == "governed" and not stale:
            clear = self._clear_distance(state, corridor)
            if clear is not None:
                limit = self._speed_limit_mps(state, clear.distance_m)
                if not vetoed and state.predicted_speed_mps(proposed) > limit:
                    governed = True
                    reason = "unobserved" if clear.end == "unobserved" else "governor"
                    applied = applied.copy()
                    applied[0] = self._command_for(state, limit, proposed)
        decision = SafetyDecision(
            vetoed=vetoed,
            hazard_distance_m=d,
            braking_distance_m=float(self._r(state.speed_mps)),
            speed_mps=float(state.speed_mps),
            safe_speed_mps=float(max_safe_speed_mps(d, self.config.braking)),
            original_action=original.copy(),
            applied_action=applied.copy(),
            perception_age_s=age,
            perception_stale=stale,
            hazard_channel=channel,
            corridor=corridor,
            reason=reason,
            governed=governed,
            steered=steered,
            clear_distance_m=clear.distance_m if clear is not None else float("nan"),
            clear_end=clear.end if clear is not None else None,
            speed_limit_mps=limit,
        )
        return (action if reason is None else applied), decision

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Filter ``action``, step the env, and add ``info["safety"]`` and ``info["cost"]``."""
        applied, decision = self.filter_action(action)
        self._holding = decision.vetoed
        if isinstance(self.env.unwrapped, DecisionSink):  # negobs envs draw the decision
            self.env.unwrapped.set_render_overlay(decision)
        obs, reward, terminated, truncated, info = self.env.step(applied)
        info = dict(info)
        info["safety"] = decision.as_dict()
        info["cost"] = decision.cost
        self.last_decision = decision
        return obs, reward, terminated, truncated, info
