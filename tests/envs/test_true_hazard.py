"""NegObsEnv.true_hazard_distance_m: the ground truth of the safety filter's d along its corridor."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from negobs_gym.core.geometry import points_in_polygon, polygon_outline_points, world_to_vehicle_xy
from negobs_gym.core.pose import Pose
from negobs_gym.envs import NegObsEnv
from negobs_gym.errors import ConfigError
from negobs_gym.safety import Corridor
from negobs_gym.spec import spec_from_toml
from tests.helpers import PITS_BESIDE_AND_AHEAD_SCENE


@pytest.fixture(scope="module")
def env() -> NegObsEnv:
    env = NegObsEnv(scenario=spec_from_toml(PITS_BESIDE_AND_AHEAD_SCENE))
    env.reset(seed=0)
    yield env
    env.close()


def _brute_force_m(corridor: Corridor, polygons: list[np.ndarray], pose: Pose) -> float:
    """The corridor's distance to every point of the polygons' areas: a 2 cm lattice inside each
    and its outline every 5 mm."""
    best = math.inf
    for poly in polygons:
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        gx, gy = np.meshgrid(np.arange(lo[0], hi[0], 0.02), np.arange(lo[1], hi[1], 0.02))
        lattice = np.column_stack([gx.ravel(), gy.ravel()])
        area = np.vstack([lattice[points_in_polygon(lattice, poly)], polygon_outline_points(poly, 0.005)])
        best = min(best, corridor.hazard_distance_m(world_to_vehicle_xy(area, [pose.x, pose.y], pose.yaw)))
    return best


def test_it_is_the_corridor_distance_to_the_obstacles_areas(env: NegObsEnv) -> None:
    car = env.vehicle.config
    start = env.vehicle.true_pose()
    pits = [ob.outline_xy_m for ob in env.terrain.negative_obstacles]
    rocks = [ob.footprint_xy_m for ob in env.terrain.positive_obstacles if not ob.in_heightfield]
    assert len(pits) == 2 and len(rocks) == 1
    found = set()
    for steer in (0.0, 0.1, 0.18, 0.25, -0.054, -0.3):  # 0.18: through the left pit; 0.0: the rock
        corridor = Corridor(
            steer_rad=steer, wheelbase_m=car.wheelbase_m, half_width_m=1.2, front_length_m=3.6
        )
        for pose in (start, dataclasses.replace(start, x=start.x - 1.0, yaw=start.yaw + 0.2)):
            for channel, polygons in (("negative", pits), ("positive", rocks)):
                truth = env.true_hazard_distance_m(corridor, pose, channel)
                brute = _brute_force_m(corridor, polygons, pose)
                assert truth == brute or abs(truth - brute) <= 0.06, (steer, channel, truth, brute)
                if math.isfinite(truth):
                    found.add((steer, channel))
    assert len(found) >= 5 and {c for _, c in found} == {"negative", "positive"}  # distances compared


def test_a_left_turn_reaches_the_pit_the_straight_strip_misses(env: NegObsEnv) -> None:
    """Why the evaluation judges a veto along the filter's corridor: steering left, the pit beside
    the start line is ahead; straight ahead the nearest is the pit on the line, 18 m farther."""
    car = env.vehicle.config
    pose = env.vehicle.true_pose()
    info_gap = env._distance_to_negative_ahead(pose) + car.length_m - car.rear_overhang_m
    strip_m = 0.5 * car.track_width_m + 1.0  # the half-width of info's wheels' strip
    straight = Corridor(steer_rad=0.0, wheelbase_m=car.wheelbase_m, half_width_m=strip_m)
    assert env.true_hazard_distance_m(straight, pose) == pytest.approx(info_gap, abs=0.05)  # the strip's
    left = dataclasses.replace(straight, steer_rad=0.18)  # R = 15 m: through the pit 6 m left, 12 m on
    assert env.true_hazard_distance_m(left, pose.as_array()) < info_gap - 10.0  # info["pose"] works


def test_a_bad_channel_is_named(env: NegObsEnv) -> None:
    corridor = Corridor(steer_rad=0.0, wheelbase_m=2.8, half_width_m=1.2)
    with pytest.raises(ConfigError, match="channel"):
        env.true_hazard_distance_m(corridor, env.vehicle.true_pose(), "ditch")  # type: ignore[arg-type]
