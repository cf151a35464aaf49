"""The speed governor (``SafetyFilterConfig(mode="governed")``): its invariant, reasons and use."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError
from negobs_gym.safety import (
    BrakingConfig,
    BrakingSafetyFilter,
    HazardState,
    SafetyFilterConfig,
    braking_distance_m,
    observed_clear_distance,
)
from negobs_gym.spec import apply_overrides, load_scenario, spec_from_toml, spec_to_toml
from tests.safety.standins import DT_S, MAX_ACCEL, MAX_BRAKE, FixedHazardEnv

GRID = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)
GOVERNED = SafetyFilterConfig(mode="governed")


def _state(
    speed: float,
    observed: np.ndarray | None,
    hazards: np.ndarray | None = None,
    *,
    age_s: float = 0.0,
) -> HazardState:
    return HazardState(
        speed_mps=speed,
        negative_obstacles_xy_m=np.zeros((0, 2)) if hazards is None else hazards,
        vehicle_width_m=2.0,
        wheelbase_m=2.8,
        front_length_m=3.65,
        max_steer_rad=math.radians(35.0),
        dt_s=DT_S,
        max_accel_mps2=MAX_ACCEL,
        max_brake_decel_mps2=MAX_BRAKE,
        time_s=10.0,
        perception_time_s=10.0 - age_s,
        observed=observed,
        grid=GRID,
        pose=Pose(x=3.0, y=4.0, yaw=0.2),
    )


def _seen_up_to(y_m: float) -> np.ndarray:
    """Every cell observed up to ``y_m`` ahead (a crest or the sensor's reach beyond)."""
    return GRID.cell_centres()[..., 1] < y_m


def _decide(state: HazardState, action=(1.0, 0.0), config: SafetyFilterConfig = GOVERNED):
    guard = BrakingSafetyFilter(FixedHazardEnv(state), config)
    return guard.filter_action(np.array(action, dtype=np.float32))


@st.composite
def _scenes(draw):
    speed = draw(st.floats(0.0, 20.0))
    reach = draw(st.floats(0.0, 30.0))  # the observed ground ends here
    observed = _seen_up_to(reach)
    for _ in range(draw(st.integers(0, 4))):  # holes: ring gaps, shadows
        row = draw(st.integers(0, GRID.rows - 1))
        col = draw(st.integers(0, GRID.cols - 1))
        observed[row : row + 3, col : col + 3] = False
    hazards = draw(st.lists(st.tuples(st.floats(-6.0, 6.0), st.floats(-3.0, 25.0)), min_size=0, max_size=5))
    action = (draw(st.floats(-1.0, 1.0)), draw(st.floats(-1.0, 1.0)))
    config = SafetyFilterConfig(
        mode="governed",
        governor_margin_m=draw(st.floats(0.0, 3.0)),
        creep_speed_mps=draw(st.floats(0.0, 3.0)),
        creep_clearance_m=draw(st.floats(0.0, 2.0)),
        unobserved_blocks=draw(st.booleans()),
    )
    return _state(speed, observed, np.array(hazards).reshape(-1, 2)), action, config


@settings(max_examples=300, deadline=None)
@given(_scenes())
def test_governor_never_outdrives_the_observed_clear_distance(scene):
    """After any action, the predicted speed v' (the protocol's one-step model,
    ``HazardState.predicted_speed_mps`` of the applied command), with c the observed clear
    distance recomputed here from the same layer, hazards and corridor, either
    (a) fits: ``c - travelled(v') >= R(v') + governor_margin_m`` (Eq. 18 against c), or
    (b) is a creep: ``v' <= creep_speed_mps`` and ``c - travelled(v') >= v'^2/(2 mu g) + v' T_r +
    front_length_m + creep_clearance_m`` (stopping leaves the bumper that far short of c), or
    (c) is what full braking leaves (nothing slower can be reached in one step).
    Tolerances 1e-9 m/s and 1e-9 m (float round-off)."""
    state, action, config = scene
    applied, decision = _decide(state, action, config)
    v_next = state.predicted_speed_mps(float(applied[0]))
    clear = observed_clear_distance(
        decision.corridor,
        GRID,
        state.observed,
        state.negative_obstacles_xy_m,
        unobserved_blocks=config.unobserved_blocks,
    )
    assert decision.clear_distance_m == clear.distance_m and decision.clear_end == clear.end
    left = clear.distance_m - state.travelled_m(v_next)
    stopping = float(braking_distance_m(v_next, config.braking)) - config.braking.buffer_m
    fits = left >= stopping + config.braking.buffer_m + config.governor_margin_m - 1e-9
    creeps = v_next <= config.creep_speed_mps + 1e-9 and left >= (
        stopping + state.front_length_m + config.creep_clearance_m - 1e-9
    )
    full_brake = state.predicted_speed_mps(-1.0)
    assert fits or creeps or v_next <= full_brake + 1e-9
    assert v_next <= max(decision.speed_limit_mps, full_brake) + 1e-9
    assert applied[1] == np.float32(action[1])  # steering is never changed
    if decision.reason is None:  # passed unchanged
        assert applied is not None and float(applied[0]) == np.float32(action[0])


def test_reasons_name_what_fired():
    far = _seen_up_to(30.0)
    # stale data: brake whatever the distance
    _, stale = _decide(_state(5.0, far, age_s=1.0))
    assert stale.reason == "stale_data" and stale.vetoed
    # a detected hazard inside R(v): Eq. 18's veto, full brake
    applied, hazard = _decide(_state(6.94, far, np.array([[0.0, 9.0]])))
    assert hazard.reason == "hazard" and hazard.vetoed and applied[0] == -1.0
    # the observed ground ends 9 m ahead (a crest): capped, for "unobserved"
    applied, crest = _decide(_state(6.94, _seen_up_to(9.0)))
    assert crest.reason == "unobserved" and crest.governed and not crest.vetoed
    assert crest.clear_end == "unobserved" and crest.clear_distance_m == pytest.approx(9.1, abs=0.11)
    assert -1.0 <= applied[0] < 1.0
    # everything seen, but 20 m/s needs far more than the grid's 25.6 m: capped, for "governor"
    _, fast = _decide(_state(20.0, far))
    assert fast.reason == "governor" and fast.clear_end == "range" and fast.governed
    # slow on open ground: passes unchanged
    applied, calm = _decide(_state(3.0, far), action=(0.2, 0.1))
    assert calm.reason is None and not calm.governed and applied[0] == np.float32(0.2)
    assert calm.speed_limit_mps > 3.0


def test_creep_lets_the_car_roll_up_to_look_and_stops_it_at_the_edge_of_the_seen():
    config = SafetyFilterConfig(mode="governed", creep_speed_mps=1.5, creep_clearance_m=1.0)
    # seen 6.1 m ahead (a crest's top): R(v') + margin fits only 0.3 m/s, the creep 1.5 m/s
    state = _state(0.0, _seen_up_to(6.1))
    applied, decision = _decide(state, config=config)
    assert decision.speed_limit_mps == 1.5 and decision.clear_end == "unobserved"
    assert applied[0] > 0 and state.predicted_speed_mps(float(applied[0])) <= 1.5
    # seen 4.5 m ahead (a pit's near rim): the bumper (3.65 m) would come within 1 m: stop
    for speed in (0.0, 1.0):
        applied, decision = _decide(_state(speed, _seen_up_to(4.5)), config=config)
        assert decision.speed_limit_mps == 0.0 and applied[0] == -1.0


def test_eq18_modes_are_unchanged_and_report_no_governor():
    state = _state(20.0, _seen_up_to(9.0))
    applied, decision = _decide(state, config=SafetyFilterConfig())
    assert decision.reason is None and not decision.governed and applied[0] == 1.0
    assert math.isnan(decision.clear_distance_m) and decision.speed_limit_mps == math.inf


def test_governor_settings_are_checked_and_reach_the_filter_by_keyword():
    with pytest.raises(ConfigError, match="creep_speed_mps"):
        SafetyFilterConfig(mode="governed", creep_speed_mps=-1.0)
    with pytest.raises(ConfigError, match="creep_clearance_m"):
        SafetyFilterConfig(mode="governed", creep_clearance_m=math.nan)
    with pytest.raises(ConfigError, match="mode"):
        SafetyFilterConfig(mode="governor")
    with pytest.raises(ConfigError, match="unobserved_blocks"):
        SafetyFilterConfig(unobserved_blocks=1)
    guard = BrakingSafetyFilter(FixedHazardEnv(_state(1.0, None)), mode="governed", governor_margin_m=2.0)
    assert guard.config.mode == "governed" and guard.config.governor_margin_m == 2.0


class _CrestCar(FixedHazardEnv):
    """A point car on a straight track; a pit 40 m ahead that its sensor sees only within 8 m
    (behind a crest), and ground observed only up to 8 m ahead while it is more than 8 m away."""

    PIT_Y_M = 40.0
    SIGHT_M = 8.0

    def __init__(self, speed: float) -> None:
        super().__init__(_state(speed, None))
        self.y, self.v, self.t = 0.0, speed, 0.0

    def hazard_state(self) -> HazardState:
        ahead = self.PIT_Y_M - self.y
        seen = _seen_up_to(min(ahead, self.SIGHT_M) if ahead > self.SIGHT_M else 30.0)
        pit = np.array([[x, ahead] for x in np.linspace(-1.0, 1.0, 11)]) if ahead <= self.SIGHT_M else None
        state = _state(self.v, seen, pit)
        return HazardState(
            **{**state.__dict__, "time_s": self.t, "perception_time_s": self.t, "pose": Pose(y=self.y)}
        )

    def step(self, action):
        a0 = float(np.clip(action[0], -1, 1))
        v_next = max(0.0, self.v + DT_S * (a0 * MAX_ACCEL if a0 >= 0 else a0 * MAX_BRAKE))
        self.y += 0.5 * DT_S * (self.v + v_next)
        self.v, self.t = v_next, self.t + DT_S
        return np.zeros(1, np.float32), 0.0, self.y + 3.65 >= self.PIT_Y_M, False, {}


@pytest.mark.parametrize(("config", "enters"), [(SafetyFilterConfig(), True), (GOVERNED, False)])
def test_a_hidden_pit_stops_the_governed_car_only(config, enters):
    car = _CrestCar(speed=10.0)
    guard = BrakingSafetyFilter(car, config)
    guard.reset(seed=0)
    for _ in range(200):
        _, _, entered, _, _ = guard.step(np.array([1.0, 0.0], np.float32))
        if entered:
            break
    assert entered == enters
    if not enters:
        assert car.v == 0.0 and car.PIT_Y_M - car.y > 3.65


def test_a_scenario_holds_the_filter_settings():
    spec = apply_overrides(load_scenario("pit_past_a_crest_25kmh"), ["filter.mode=brake"])
    assert spec.filter.mode == "brake"
    with pytest.raises(ConfigError, match=r"filter\.mode"):
        apply_overrides(spec, ["filter.mode=fast"])
    with pytest.raises(ConfigError, match=r"filter\.creep_speed_mps"):
        apply_overrides(spec, ["filter.creep_speed_mps=-1"])
    toml = 'name = "m"\n[terrain]\npreset = "braking_track"\n[filter]\nhazard_memory = true\n'
    toml += "governor_margin_m = 2.0\n[filter.braking]\nbuffer_m = 6.0\n"
    spec = spec_from_toml(toml)
    assert spec.filter == SafetyFilterConfig(  # laid over the scenes' defaults (the 8 m hold)
        hazard_memory=True,
        hazard_memory_hold_m=8.0,
        governor_margin_m=2.0,
        braking=BrakingConfig(buffer_m=6.0),
    )
    assert spec_from_toml(spec_to_toml(spec)) == spec
    # the keys [run] held before, for one release
    with pytest.warns(DeprecationWarning, match=r"run\.filter_mode is now filter\.mode"):
        old = apply_overrides(load_scenario("braking_v0"), ["run.filter_mode=governed"])
    assert old.filter.mode == "governed"
