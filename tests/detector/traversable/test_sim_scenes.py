"""Paper T's scenes from the simulator: PyBullet terrain, the paper T LUX rig, the detector end to end.

The LUX (2.0 m ahead of the pose origin, 0.65 m up, pitched down 5.03 deg) sees the ground 6–10 m
ahead of that origin, so each scene is scanned from a station that puts its obstacle (or the bend)
in that band. The vehicle stands on its four wheels: roll and pitch follow the terrain under them
(the courses have gentle slopes of a few degrees; a level pose on a 2 deg side slope pulls the
uphill scan lines in until they end at the edge of the field of view).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from negobs_gym.core import GridSpec, Pose
from negobs_gym.detector.traversable import TraversableConfig, TraversableRegion, TraversableRegionDetector
from negobs_gym.sensors.lidar import scan
from negobs_gym.sensors.models import ibeo_lux
from negobs_gym.sensors.raycast.pybullet_backend import PyBulletCaster
from negobs_gym.sensors.rigs import paper_t_rig
from negobs_gym.sim import BorderConfig, presets
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import VehicleConfig
from negobs_gym.sim.world import World, WorldConfig

FRAMES = 5
STEP_M = 0.7  # 7 m/s at 10 Hz
TRACK_HALF_WIDTH_M = 3.0  # TerrainConfig default track width 6 m
FOOT_M = TRACK_HALF_WIDTH_M + BorderConfig().verge_width_m  # where a bank / drop-off begins
# The scenes' stations and the robustness sweep of docs/detector_traversable.md were laid out with
# the LUX 2.0 m ahead of the pose origin (the envs' mount before it moved to the bumper); no vehicle
# body is in these scenes, so only the pose's origin moves with it.
LUX_FORWARD_M = 2.0
LUX_GROUND_Y_M = (6.0, 10.0)  # vehicle-frame band of the LUX's ground hits


def _pose_on_wheels(terrain: Terrain, station_m: float) -> Pose:
    """Pose at a track station with the chassis resting on the terrain under its four wheels."""
    vehicle = VehicleConfig()
    xy, yaw = terrain.track.pose_at(station_m)
    xy = np.asarray(xy, dtype=np.float64)
    fwd = np.array([-math.sin(yaw), math.cos(yaw)])
    right = np.array([math.cos(yaw), math.sin(yaw)])
    half = 0.5 * vehicle.track_width_m
    rear = terrain.heightfield.height_at(np.stack([xy - half * right, xy + half * right]))
    front_xy = xy + vehicle.wheelbase_m * fwd
    front = terrain.heightfield.height_at(np.stack([front_xy - half * right, front_xy + half * right]))
    pitch = math.atan2(float(front.mean() - rear.mean()), vehicle.wheelbase_m)  # nose up > 0
    roll = math.atan2(float((rear[0] - rear[1]) + (front[0] - front[1])) / 2, vehicle.track_width_m)
    return Pose(float(xy[0]), float(xy[1]), float(rear.mean()), roll, pitch, float(yaw))


@functools.cache
def _drive_and_detect(preset, station_m: float, seed: int = 0) -> tuple[TraversableRegion, Pose, Terrain]:
    """Scan FRAMES noisy LUX frames while moving along the track centre; return the last result."""
    terrain = preset(seed=seed)
    mount = paper_t_rig(lux=ibeo_lux(hfov_deg=110.0), forward_m=LUX_FORWARD_M).mounts[0]
    rng = np.random.default_rng(seed)
    detector = TraversableRegionDetector(TraversableConfig())
    with World(terrain, WorldConfig()) as world:
        caster = PyBulletCaster(world.client_id)
        for k in range(FRAMES):
            pose = _pose_on_wheels(terrain, station_m + STEP_M * k)
            result = detector.update(scan(mount, caster, pose, rng=rng), pose)
    return result, pose, terrain


def _true_edge(terrain: Terrain, pose: Pose, lateral_m: float) -> tuple[float, float]:
    """Least-squares ``(slope, x at 8 m)`` of the track line at ``lateral_m``, in the vehicle frame,
    over the band the LUX sees."""
    station = np.linspace(0.0, terrain.track.length_m, 4001)
    xy, _ = terrain.track.pose_at(station, lateral_m)
    ground = terrain.heightfield.height_at(xy)
    v = pose.to_vehicle(np.column_stack([xy, ground]))
    band = (v[:, 1] >= LUX_GROUND_Y_M[0]) & (v[:, 1] <= LUX_GROUND_Y_M[1])
    slope, offset = np.polyfit(v[band, 1], v[band, 0], 1)
    return float(slope), float(slope * 8.0 + offset)


@pytest.mark.parametrize(
    ("preset", "station_m"),
    [
        (presets.oncoming_car, 26.0),
        (presets.parked_motorbike, 15.0),
        (presets.pedestrian_near_dropoff, 15.0),
    ],
)
def test_scene_obstacle_is_one_cluster_at_its_true_place_and_not_traversable(preset, station_m):
    result, pose, terrain = _drive_and_detect(preset, station_m)
    (truth,) = terrain.positive_obstacles
    truth_xy = pose.to_vehicle(np.asarray(truth.centre_m))[:2]
    distances = [float(np.linalg.norm(ob.centre_xy_m - truth_xy)) for ob in result.obstacles]
    assert distances, f"no obstacle cluster for the {truth.kind}"
    near = [d for d in distances if d < 1.5]
    assert len(near) >= 1, f"{truth.kind}: nearest cluster {min(distances):.2f} m from the truth"
    row, col, inside = GridSpec().cell_of(truth_xy)  # the detector's default grid
    assert inside
    assert not result.traversable[row, col], "the obstacle's own cell must be cut from the region"
    assert result.positive_obstacles.any()


def test_straight_banked_track_boundaries_are_parallel_and_at_the_bank_feet():
    result, _, _ = _drive_and_detect(presets.straight_banked_track, 20.0)
    for line, foot_x in ((result.left_line, -FOOT_M), (result.right_line, FOOT_M)):
        assert line is not None
        assert abs(line.slope) < 0.1
        assert abs(line.x_at(8.0) - foot_x) < 0.6


def test_left_bend_boundaries_lean_left_like_the_track():
    # Paper T Fig. 11: in the bend both lines lean its way. At station 20 the vehicle enters the
    # 30 m-radius arc and its LUX lines lie 7-11 m into it (the bank feet lean by -0.2 to -0.3).
    result, pose, terrain = _drive_and_detect(presets.bend, 20.0)
    for line, lateral in ((result.left_line, -FOOT_M), (result.right_line, FOOT_M)):
        assert line is not None
        true_slope, _ = _true_edge(terrain, pose, lateral)
        assert true_slope < -0.15, "scene: the LUX must look into the arc"
        assert line.slope < 0
        assert abs(line.slope - true_slope) < 0.15


def test_pedestrian_scene_keeps_the_drop_off_out_of_the_region():
    # Paper T Fig. 14: the right side of the track falls away (a drop-off 1.5 m past the track
    # edge); the right boundary must stay on the near side of the drop-off's edge.
    result, pose, terrain = _drive_and_detect(presets.pedestrian_near_dropoff, 15.0)
    assert result.right_line is not None and result.traversable.any()
    _, edge_x = _true_edge(terrain, pose, FOOT_M)
    ys = np.linspace(*LUX_GROUND_Y_M, 9)
    assert (result.right_line.x_at(ys) <= edge_x + 0.2).all()
    assert (result.right_line.x_at(ys) >= edge_x - 1.0).all()  # and not far inside the track
    # Cells over the drop-off (its face and floor) are never traversable.
    grid = GridSpec()
    station = np.linspace(0.0, terrain.track.length_m, 2001)
    for lateral in (FOOT_M + 0.5, FOOT_M + 1.5):
        xy, _ = terrain.track.pose_at(station, lateral)
        v = pose.to_vehicle(np.column_stack([xy, terrain.heightfield.height_at(xy)]))[:, :2]
        v = v[(v[:, 1] >= LUX_GROUND_Y_M[0]) & (v[:, 1] <= LUX_GROUND_Y_M[1])]
        rows, cols, inside = grid.cell_of(v)
        assert inside.all()
        assert not result.traversable[rows, cols].any()
