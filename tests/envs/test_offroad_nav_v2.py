"""OffroadTrack-v0 (OffroadNavV2Env): OffroadNav-v1's course where leaving the track ends the
episode; every obstacle passable on it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from negobs_gym.core.geometry import vehicle_to_world_xy
from negobs_gym.envs.scenarios import OffroadNavV1Env, OffroadNavV2Env
from negobs_gym.sim import track_coordinates
from negobs_gym.sim.presets import winding_course
from negobs_gym.sim.vehicle import VehicleConfig

SPARE_M = 0.5  # clearance beside the car when it passes an obstacle with its centre on the track


ORACLE_GRID = {"observation.source": "oracle"}
#: ... on the shortest winding course (60 m: a world builds ~4x faster); what the tests below check
#: does not depend on the course's length
SHORT_ORACLE = {**ORACLE_GRID, "terrain.params.length_m": 60.0}


def _footprints(terrain) -> list[np.ndarray]:
    """Outline points (N, 2) of every obstacle a car cannot drive over (mounds are part of the
    heightfield and drivable)."""
    shapes = [ob.outline_xy_m for ob in terrain.negative_obstacles]
    for ob in terrain.positive_obstacles:
        if not ob.in_heightfield:
            hx, hy = ob.half_extents_m[:2]  # body frame: x right, y forward
            local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
            shapes.append(vehicle_to_world_xy(local, ob.centre_m[:2], ob.yaw_rad))
    return shapes


@pytest.mark.parametrize("seed", range(6))
def test_every_obstacle_can_be_passed_on_the_track(seed: int) -> None:
    terrain = winding_course(120.0, seed=seed)
    half_track = 0.5 * terrain.track.width_m
    need = 0.5 * VehicleConfig().width_m + SPARE_M  # car centre to the obstacle's side
    for outline in _footprints(terrain):
        _, lateral = track_coordinates(terrain.track, np.asarray(outline, dtype=np.float64))
        left_gap = lateral.min() + half_track  # room between the track's left edge and the obstacle
        right_gap = half_track - lateral.max()
        assert max(left_gap, right_gap) >= need, (seed, lateral.min(), lateral.max())


def test_v2_is_v1_with_the_off_track_rule_and_its_cost() -> None:
    v1 = OffroadNavV1Env(overrides=SHORT_ORACLE)
    v2 = OffroadNavV2Env(overrides=SHORT_ORACLE)
    assert set(v2.scenario.terminations) - set(v1.scenario.terminations) == {"off_track"}
    assert v2.scenario.reward == dataclasses.replace(v1.scenario.reward, off_track=-100.0)
    assert v2.scenario.observation == v1.scenario.observation
    v1.reset(seed=11)
    v2.reset(seed=11)
    assert [o.outline_xy_m.tobytes() for o in v1.terrain.negative_obstacles] == [
        o.outline_xy_m.tobytes() for o in v2.terrain.negative_obstacles
    ]
    v1.close()
    v2.close()


def test_leaving_the_track_ends_a_v2_episode_only() -> None:
    ends = {}
    for env_cls in (OffroadNavV1Env, OffroadNavV2Env):
        env = env_cls(overrides=SHORT_ORACLE)
        env.reset(seed=0)
        steps, terminated = 0, False
        while not terminated and steps < 60:  # steering half right: a ~9 m radius circle, off the track
            _, _, terminated, _, info = env.step(np.array([0.8, -0.5], np.float32))
            steps += 1
        ends[env_cls] = (steps, info["termination"], info["off_track"], info["rewards"]["off_track"])
        env.close()
    steps, rules, off, cost = ends[OffroadNavV2Env]
    assert rules == ["off_track"] and off and steps < 60 and cost == -100.0
    assert ends[OffroadNavV1Env] == (60, [], True, 0.0)  # v1 drives on beside the track, at no cost
    assert ends[OffroadNavV1Env][2]
