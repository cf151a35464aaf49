"""Paper T's scenes from the simulator: PyBullet terrain, the paper T LUX rig, the detector end to end.

The LUX (0.65 m, pitched down 5.03 deg) sees the ground 6–10 m ahead of the bumper, so each scene is
scanned from a station that puts its obstacle in that band.
"""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.core import GridSpec, Pose
from negobs_gym.detector.traversable import TraversableConfig, TraversableRegion, TraversableRegionDetector
from negobs_gym.sensors.lidar import scan
from negobs_gym.sensors.models import ibeo_lux
from negobs_gym.sensors.raycast.pybullet_backend import PyBulletCaster
from negobs_gym.sensors.rigs import paper_t_rig
from negobs_gym.sim import presets
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.world import World, WorldConfig

FRAMES = 5
STEP_M = 0.7  # 7 m/s at 10 Hz


def _drive_and_detect(terrain: Terrain, station_m: float, seed: int = 0) -> tuple[TraversableRegion, Pose]:
    """Scan FRAMES noisy LUX frames while moving along the track centre; return the last result."""
    mount = paper_t_rig(lux=ibeo_lux(hfov_deg=110.0)).mounts[0]
    rng = np.random.default_rng(seed)
    detector = TraversableRegionDetector(TraversableConfig())
    with World(terrain, WorldConfig()) as world:
        caster = PyBulletCaster(world.client_id)
        for k in range(FRAMES):
            xy, yaw = terrain.track.pose_at(station_m + STEP_M * k)
            z = float(terrain.heightfield.height_at(np.asarray(xy)))
            pose = Pose(float(xy[0]), float(xy[1]), z, 0.0, 0.0, float(yaw))
            result = detector.update(scan(mount, caster, pose, rng=rng), pose)
    return result, pose


@pytest.mark.parametrize(
    ("preset", "station_m"),
    [
        (presets.oncoming_car, 26.0),
        (presets.parked_motorbike, 15.0),
        (presets.pedestrian_near_dropoff, 15.0),
    ],
)
def test_scene_obstacle_is_one_cluster_at_its_true_place_and_not_traversable(preset, station_m):
    terrain = preset(seed=0)
    (truth,) = terrain.positive_obstacles
    result, pose = _drive_and_detect(terrain, station_m)
    truth_xy = pose.to_vehicle(np.asarray(truth.centre_m))[:2]
    distances = [float(np.linalg.norm(ob.centre_xy_m - truth_xy)) for ob in result.obstacles]
    assert distances, f"no obstacle cluster for the {truth.kind}"
    near = [d for d in distances if d < 1.5]
    assert len(near) >= 1, f"{truth.kind}: nearest cluster {min(distances):.2f} m from the truth"
    row, col, inside = GridSpec().cell_of(truth_xy)  # the detector's default grid
    assert inside
    assert not result.traversable[row, col], "the obstacle's own cell must be cut from the region"
    assert result.positive_obstacles.any()


@pytest.mark.xfail(
    strict=True,
    reason="known defect: on simulated banks the left boundary tilts (slope ~-0.5); synthetic scans pass",
)
def test_straight_banked_track_boundaries_are_parallel_and_at_the_bank_feet():
    result, _ = _drive_and_detect(presets.straight_banked_track(seed=0), 20.0)
    for line, foot_x in ((result.left_line, -4.5), (result.right_line, 4.5)):
        assert line is not None
        assert abs(line.slope) < 0.1
        assert abs(line.x_at(8.0) - foot_x) < 0.6


@pytest.mark.xfail(strict=True, reason="known defect: on the simulated left bend the right line leans right")
def test_left_bend_boundaries_lean_left():
    result, _ = _drive_and_detect(presets.bend(seed=0), 14.0)
    assert result.left_line is not None and result.right_line is not None
    assert result.left_line.slope < 0 and result.right_line.slope < 0
