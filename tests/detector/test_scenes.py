"""Simulated scene tests of the paper N negative-obstacle detector (issue 4, noise on).

Terrain presets, the PyBullet world and the vehicle give the ground truth and the pose; the sensor
rig (``negobs_gym.sensors``) synthesises the structured scans; ``NegativeObstacleDetector`` fuses
them; ``negobs_gym.eval`` matches its obstacles to the ground truth on the 20 cm grid.

The hooks into the sensors and the detector live in :func:`_make_scanner` and
:func:`_obstacle_outlines`. The ground-truth checks at the top run without those parts.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.detector import NegativeObstacleDetector
from negobs_gym.eval import (
    DetectionEvalConfig,
    RecallTable,
    match_frame,
    rasterize_outline,
    track_border_mask,
    world_outline_to_vehicle,
)
from negobs_gym.sensors.lidar import scan_rig
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sensors.rigs import paper_n_rig, paper_n_rig_reduced
from negobs_gym.sim.presets import braking_track, clutter_track, rough_track
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

GRID = GridSpec()
FRAME_S = 0.1  # 10 Hz sensor frames (paper N: HDL-64/HDL-32 at 10 Hz)
PIT = {"ditch_length_m": 1.0, "ditch_width_m": 1.0, "ditch_depth_m": 0.8}  # issue 4: 1.0 x 1.0 x 0.8 m


def _start_pose(terrain: Terrain) -> Pose:
    x, y, yaw = terrain.start_xy_yaw
    return Pose(x=x, y=y, z=0.0, roll=0.0, pitch=0.0, yaw=yaw)


# --- ground truth on the grid (runs without sensors or detector) ------------------------------


@pytest.mark.parametrize("distance_m", [8.0, 12.0])
def test_braking_pit_ground_truth_on_grid(distance_m: float) -> None:
    terrain = braking_track(ditch_distance_m=distance_m, seed=0, **PIT)
    (pit,) = terrain.negative_obstacles
    outline = world_outline_to_vehicle(pit.outline_xy_m, _start_pose(terrain))
    cells = rasterize_outline(outline, GRID)
    # a 1 m x 1 m rim: 25 cells of 20 cm (a carving on the 10 cm terrain grid may shift it a cell)
    assert 20 <= cells.sum() <= 30
    ys = GRID.cell_centres()[..., 1][cells]
    xs = GRID.cell_centres()[..., 0][cells]
    assert distance_m - 0.2 <= ys.min() and ys.max() <= distance_m + 1.2
    assert np.all(np.abs(xs) <= 0.7)
    m = match_frame([], [outline], GRID)
    # nearest cell centre is one half cell beyond the near edge, straight ahead
    assert m.truth_distance_m[0] == pytest.approx(distance_m, abs=0.35)
    assert not m.truth_recalled[0]


def test_rough_track_has_no_negative_obstacles_and_border_band_is_off_centre() -> None:
    terrain = rough_track(length_m=40.0, seed=3)
    assert terrain.negative_obstacles == ()
    pose = _start_pose(terrain)
    centre = world_outline_to_vehicle(terrain.track.centreline_xy_m, pose)
    border = track_border_mask(centre, terrain.track.width_m, GRID, DetectionEvalConfig().border_band_m)
    row, col, inside = GRID.cell_of(np.array([0.0, 10.0]))
    assert inside and not border[row, col]  # the track centre is never excused
    edge = np.array([0.5 * terrain.track.width_m, 10.0])
    row, col, inside = GRID.cell_of(edge)
    assert not inside or border[row, col]


# --- hooks into the sensors and detector parts --------------------------------------------------


def _make_scanner(world, vehicle, rng: np.random.Generator, native: bool) -> Callable[[], dict]:
    """Return ``scan() -> {sensor name: StructuredScan}`` for paper N's rig on the vehicle (noise on).

    Paper N rig (native or reduced), the fast ray caster (PyBullet without embreex) that ignores
    the vehicle's own body, default sensor noise drawn from ``rng``.
    """
    rig = paper_n_rig() if native else paper_n_rig_reduced()
    caster = make_caster(world, "auto", exclude_body_ids=(vehicle.body_id,))

    def scan() -> dict:
        return scan_rig(rig, caster, vehicle.true_pose(), rng=rng)

    return scan


def _obstacle_outlines(detection) -> list[np.ndarray]:
    """Vehicle-frame outlines of a ``Detection``'s obstacles (issue 4: outline polygon per obstacle)."""
    return [np.asarray(o.outline_xy_m) for o in detection.obstacles]


def _run_frames(terrain, n_frames: int, speed_mps: float, native: bool, seed: int):
    """Yield (detection, true pose) per 10 Hz frame with the vehicle held at ``speed_mps``."""
    rng = np.random.default_rng(seed)
    detector = NegativeObstacleDetector()
    with World(terrain) as world:
        vehicle = Vehicle(world, rng=rng)
        scan = _make_scanner(world, vehicle, rng, native)
        steps = round(FRAME_S / world.config.time_step_s)
        world.step(steps)  # settle on the suspension
        for _ in range(n_frames):
            vehicle.set_speed(speed_mps)
            world.step(steps)
            detection = detector.update(scan(), vehicle.pose())
            yield detection, vehicle.true_pose()


def _pit_recalled(distance_m: float, native: bool, n_frames: int) -> tuple[bool, int]:
    terrain = braking_track(ditch_distance_m=distance_m, seed=1, **PIT)
    (pit,) = terrain.negative_obstacles
    detection, pose = list(_run_frames(terrain, n_frames, speed_mps=0.0, native=native, seed=7))[-1]
    truth = world_outline_to_vehicle(pit.outline_xy_m, pose, pit.floor_z_m + pit.depth_m)
    match = match_frame(_obstacle_outlines(detection), [truth], GRID)
    grid_hit = int(np.count_nonzero(np.asarray(detection.grid, dtype=bool) & rasterize_outline(truth, GRID)))
    return bool(match.truth_recalled[0]), grid_hit


# --- scene acceptance ---------------------------------------------------------------------------


@pytest.mark.parametrize("distance_m", [8.0, 12.0])
def test_pit_is_in_fused_grid_reduced_rig(distance_m: float) -> None:
    recalled, grid_hit = _pit_recalled(distance_m, native=False, n_frames=4)
    assert recalled, f"pit at {distance_m} m not among the detected obstacles"
    assert grid_hit > 0, f"pit at {distance_m} m has no cell in the fused grid"


@pytest.mark.slow
@pytest.mark.parametrize("distance_m", [8.0, 12.0])
def test_pit_is_in_fused_grid_native_rig(distance_m: float) -> None:
    recalled, grid_hit = _pit_recalled(distance_m, native=True, n_frames=4)
    assert recalled and grid_hit > 0


def _false_alarms(length_m: float, n_frames: int, native: bool) -> RecallTable:
    terrain = rough_track(length_m=length_m, seed=5)
    cfg = DetectionEvalConfig()
    table = RecallTable(cfg)
    speed = 10.0  # 10 m/s at 10 Hz: one frame per metre, 100 frames per 100 m
    for detection, pose in _run_frames(terrain, n_frames, speed_mps=speed, native=native, seed=11):
        centre = world_outline_to_vehicle(terrain.track.centreline_xy_m, pose)
        border = track_border_mask(centre, terrain.track.width_m, GRID, cfg.border_band_m)
        table.add(match_frame(_obstacle_outlines(detection), [], GRID, cfg, border_mask=border))
    return table


def test_rough_track_false_alarms_short() -> None:
    table = _false_alarms(length_m=60.0, n_frames=20, native=False)
    # <= 1 per 100 frames; over 20 frames that allows none
    assert table.frames == 20
    assert table.false_alarms == 0, f"{table.false_alarms} false obstacles in 20 frames"


@pytest.mark.slow
def test_rough_track_false_alarms_100m_native() -> None:
    table = _false_alarms(length_m=140.0, n_frames=100, native=True)
    assert table.frames == 100
    assert table.false_alarms <= 1, f"{table.false_alarms} false obstacles per 100 frames"
    assert math.isfinite(table.false_alarms_per_frame())


# --- clutter (issue 10): walls + embankment, parked vehicles, rock fields, vegetation -----------


def _clutter_false_alarms(n_frames: int, native: bool, pits: bool, seed: int) -> tuple[int, int, int]:
    """Drive ``clutter_track`` at 10 m/s (one frame per metre): (frames, false obstacles on the
    track, frames in which a pit within 6-20 m is recalled)."""
    terrain = clutter_track(seed=seed, pits=pits, length_m=30.0 + n_frames)
    frames = false_on_track = recalled = 0
    for detection, pose in _run_frames(terrain, n_frames, speed_mps=10.0, native=native, seed=seed + 11):
        frames += 1
        centre = world_outline_to_vehicle(terrain.track.centreline_xy_m, pose)
        # cells on the track: within half the track width of the centre line
        track = track_border_mask(centre, 1e-6, GRID, 0.5 * terrain.track.width_m)
        truths = [
            world_outline_to_vehicle(o.outline_xy_m, pose, o.floor_z_m + o.depth_m)
            for o in terrain.negative_obstacles
        ]
        truth_cells = [rasterize_outline(t, GRID) for t in truths]
        for outline in _obstacle_outlines(detection):
            cells = rasterize_outline(outline, GRID)
            if (cells & track).any() and not any((cells & t).any() for t in truth_cells):
                false_on_track += 1
        m = match_frame(_obstacle_outlines(detection), truths, GRID)
        near = (m.truth_distance_m >= 6.0) & (m.truth_distance_m <= 20.0)
        recalled += int(np.any(m.truth_recalled & near))
    return frames, false_on_track, recalled


def test_clutter_track_false_alarms_short() -> None:
    frames, false_on_track, _ = _clutter_false_alarms(n_frames=20, native=False, pits=False, seed=0)
    # <= 1 per 100 frames; over 20 frames that allows none
    assert frames == 20
    assert false_on_track == 0, f"{false_on_track} false obstacles on the track in 20 frames of clutter"


@pytest.mark.slow
@pytest.mark.parametrize("pits", [False, True])
def test_clutter_track_false_alarms_100m_native(pits: bool) -> None:
    frames, false_on_track, recalled = _clutter_false_alarms(n_frames=100, native=True, pits=pits, seed=1)
    assert frames == 100
    assert false_on_track <= 1, f"{false_on_track} false obstacles on the track per 100 frames"
    if pits:  # the clutter does not hide the pits on the track
        assert recalled >= 30, f"a pit 6-20 m ahead recalled in only {recalled} of 100 frames"
