"""Hazard memory: hazards kept in the world frame with the INS pose until seen clear again."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.errors import ConfigError, InterfaceError
from negobs_gym.eval.scenario_runner import run_scenario_seeds
from negobs_gym.safety import BrakingSafetyFilter, HazardMemory, HazardState, SafetyFilterConfig
from negobs_gym.spec import load_scenario
from tests.safety.standins import DT_S, MAX_ACCEL, MAX_BRAKE, FixedHazardEnv

GRID = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)
PIT = np.array([[x, 12.1] for x in np.linspace(-0.9, 0.9, 10)])  # a pit's rim 12 m ahead


def _forward(pose: Pose, metres: float, rng: np.random.Generator | None = None) -> Pose:
    """``pose`` moved along its heading; with ``rng``, an INS reading of it (5 cm, 0.3 deg noise)."""
    x = pose.x - metres * math.sin(pose.yaw)
    y = pose.y + metres * math.cos(pose.yaw)
    if rng is None:
        return Pose(x=x, y=y, yaw=pose.yaw)
    return Pose(
        x=x + rng.normal(0, 0.05), y=y + rng.normal(0, 0.05), yaw=pose.yaw + math.radians(rng.normal(0, 0.3))
    )


def test_memory_carries_hazards_with_the_ins_pose_under_noise():
    rng = np.random.default_rng(7)
    memory = HazardMemory()
    true = Pose(x=2.0, y=1.0, yaw=0.4)
    memory.update(PIT, true, GRID, np.ones(GRID.shape, dtype=bool))
    blind = np.zeros(GRID.shape, dtype=bool)  # nothing seen: the rim is in the blind disc
    for _ in range(7):  # 7 m closer, the detector reports nothing
        true = _forward(true, 1.0)
        held = memory.update(np.zeros((0, 2)), _forward(true, 0.0, rng), GRID, blind)
    assert len(held) == len(PIT)
    # 5.1 m ahead now, within the INS noise (5 cm, 0.3 deg at ~12 m: ~0.1 m, plus a cell)
    assert np.abs(held[:, 1] - 5.1).max() < 0.35
    assert np.abs(np.sort(held[:, 0]) - PIT[:, 0]).max() < 0.35


def test_memory_releases_a_hazard_when_its_cell_is_seen_clear_only():
    memory = HazardMemory()
    pose = Pose(x=0.0, y=0.0, yaw=0.0)
    memory.update(PIT[:1], pose, GRID, None)
    seen = np.ones(GRID.shape, dtype=bool)
    # seen again with a hazard in that cell: kept (once)
    assert len(memory.update(PIT[:1] + 0.01, pose, GRID, seen)) == 1
    # its cell unobserved (and the detector quiet): kept
    unseen = seen.copy()
    row, col, _ = GRID.cell_of(PIT[0])
    unseen[row, col] = False
    assert len(memory.update(np.zeros((0, 2)), pose, GRID, unseen)) == 1
    # observed, no hazard: released
    assert len(memory.update(np.zeros((0, 2)), pose, GRID, seen)) == 0
    # a hazard behind the grid stays: no sensor sees it
    memory.update(np.array([[0.0, -10.0]]), pose, GRID, seen)
    assert len(memory.update(np.zeros((0, 2)), pose, GRID, seen)) == 1


def test_within_the_hold_distance_a_point_seen_clear_is_kept():
    """Closing in, the detector loses a pit whose cells still return: within ``hold_m`` of the
    rear axle the memory keeps its points, beyond it releases them."""
    pose = Pose(x=0.0, y=0.0, yaw=0.0)
    seen = np.ones(GRID.shape, dtype=bool)
    near, far = np.array([[0.5, 6.1]]), np.array([[0.5, 9.1]])
    holding = HazardMemory(hold_m=8.0)
    holding.update(np.concatenate([near, far]), pose, GRID, seen)
    held = holding.update(np.zeros((0, 2)), pose, GRID, seen)
    np.testing.assert_allclose(held, near)
    plain = HazardMemory()
    plain.update(np.concatenate([near, far]), pose, GRID, seen)
    assert len(plain.update(np.zeros((0, 2)), pose, GRID, seen)) == 0
    # the filter builds its memory with the config's distance, which must be finite and >= 0
    assert SafetyFilterConfig(hazard_memory=True, hazard_memory_hold_m=8.0).hazard_memory_hold_m == 8.0
    with pytest.raises(ConfigError, match="hazard_memory_hold_m"):
        SafetyFilterConfig(hazard_memory_hold_m=-1.0)
    with pytest.raises(ConfigError, match="hold_m"):
        HazardMemory(hold_m=float("nan"))


def _state(hazards: np.ndarray, speed: float = 0.0) -> HazardState:
    return HazardState(
        speed_mps=speed,
        negative_obstacles_xy_m=hazards,
        vehicle_width_m=2.0,
        wheelbase_m=2.8,
        front_length_m=3.65,
        max_steer_rad=math.radians(35.0),
        dt_s=DT_S,
        max_accel_mps2=MAX_ACCEL,
        max_brake_decel_mps2=MAX_BRAKE,
        time_s=1.0,
        perception_time_s=1.0,
        observed=GRID.cell_centres()[..., 1] > 7.0,  # the blind disc: nothing seen within 7 m
        grid=GRID,
        pose=Pose(x=1.0, y=2.0, yaw=0.1),
    )


@pytest.mark.parametrize(("memory", "vetoed"), [(False, False), (True, True)])
def test_a_pit_that_drops_out_of_the_detection_still_stops_the_car(memory, vetoed):
    """A car standing 5 m before a pit whose cells the detector lost (its rim in the blind disc):
    only the filter with hazard memory still vetoes the throttle."""
    env = FixedHazardEnv(_state(PIT - [0.0, 7.05]))  # R(v') + travelled = 5.1 m > 5.05 m
    guard = BrakingSafetyFilter(env, SafetyFilterConfig(release_margin_m=0.0, hazard_memory=memory))
    guard.reset(seed=0)
    guard.step(np.array([-1.0, 0.0], np.float32))  # the pit, seen
    env.state = _state(np.zeros((0, 2)))  # lost
    _, _, _, _, info = guard.step(np.array([1.0, 0.0], np.float32))
    assert info["safety"]["vetoed"] is vetoed
    assert (info["safety"]["hazard_distance_m"] == pytest.approx(5.05)) is vetoed


@pytest.mark.parametrize(("hold_m", "vetoed"), [(0.0, False), (8.0, True)])
def test_a_pit_lost_while_its_cells_still_return_stops_the_car_within_the_hold(hold_m, vetoed):
    """As above, but the pit's cells hold returns when the detector loses it (paper N's pairs
    gone, the floor in view): only a hold distance keeps the memory from releasing it."""
    env = FixedHazardEnv(_state(PIT - [0.0, 7.05]))
    config = SafetyFilterConfig(release_margin_m=0.0, hazard_memory=True, hazard_memory_hold_m=hold_m)
    guard = BrakingSafetyFilter(env, config)
    guard.reset(seed=0)
    guard.step(np.array([-1.0, 0.0], np.float32))
    everywhere = np.ones(GRID.shape, dtype=bool)
    env.state = dataclasses.replace(_state(np.zeros((0, 2))), observed=everywhere)
    _, _, _, _, info = guard.step(np.array([1.0, 0.0], np.float32))
    assert info["safety"]["vetoed"] is vetoed


def test_memory_needs_the_pose_and_grid():
    bare = HazardState(**{**_state(PIT).__dict__, "pose": None})
    guard = BrakingSafetyFilter(FixedHazardEnv(bare), hazard_memory=True)
    with pytest.raises(InterfaceError, match="pose"):
        guard.step(np.array([0.0, 0.0], np.float32))


def test_the_creeping_scene_runs_the_stop_and_go_driver_behind_the_memory():
    spec = load_scenario("pit_creep_stop_and_go")
    assert spec.run.driver == "creeping" and spec.run.target_speed_mps == 1.5
    assert spec.filter.hazard_memory and spec.filter.release_margin_m == 0.0


# slow (end to end, ~1 min a seed): the memory's property is checked step by step by
# test_a_pit_that_drops_out_of_the_detection_still_stops_the_car
@pytest.mark.slow
def test_a_creeping_driver_stops_short_of_the_pit_behind_the_memory():
    """Stop and go towards paper N's 150 x 60 cm pit with release_margin 0: the memory keeps the
    pit, so the front bumper stays about B - (rear axle to bumper) short of the rim."""
    (result,) = run_scenario_seeds("pit_creep_stop_and_go", seeds=[1])
    assert not result.entered_negative_obstacle and result.final_gap_m > 1.0
