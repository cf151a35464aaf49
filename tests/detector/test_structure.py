"""Positive obstacles from paper N's rig: returns above the ROI ground map (detector/structure.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose
from negobs_gym.detector import (
    NegativeObstacleDetector,
    RoiConfig,
    StructureConfig,
    StructureDetector,
    build_ground_map,
    structure_points,
)
from negobs_gym.detector.memory import PointHold
from negobs_gym.detector.synthetic import Block, Hole, hdl32_side_scan, hdl64_scan

GRID = GridSpec(ahead_m=25.6, back_m=3.2, side_m=6.4)  # the envs' observation grid
ROCK = Block(x0_m=-0.4, x1_m=0.4, y0_m=10.0, y1_m=10.6, height_m=0.5)  # a 0.8 x 0.6 x 0.5 m rock


def rig(holes=(), blocks=()) -> dict:
    """Paper N's three sensors over the synthetic plane."""
    return {
        "hdl64": hdl64_scan(holes, blocks=blocks),
        "hdl32_left": hdl32_side_scan(holes, blocks=blocks, side="left"),
        "hdl32_right": hdl32_side_scan(holes, blocks=blocks, side="right"),
    }


def footprint(grid: GridSpec, block: Block) -> np.ndarray:
    """Cells whose centre lies on the block's footprint."""
    c = grid.cell_centres()
    x, y = c[..., 0], c[..., 1]
    return (x > block.x0_m) & (x < block.x1_m) & (y > block.y0_m) & (y < block.y1_m)


def test_a_rock_is_marked_over_its_footprint_not_only_its_face() -> None:
    """The HDL-64 sees the rock's top: every cell of its footprint is set, and nothing else but the
    row of its near face."""
    grid = StructureDetector(grid=GRID).update(rig(blocks=[ROCK]), Pose())
    inside = footprint(GRID, ROCK)
    assert inside.sum() == 12 and grid[inside].all()
    rows = np.flatnonzero(grid.any(axis=1))
    near_face_row = GRID.cell_of(np.array([0.0, ROCK.y0_m - 0.01]))[0]
    assert set(rows) <= set(np.flatnonzero(inside.any(axis=1))) | {int(near_face_row)}


def test_flat_ground_and_a_pit_give_no_structure() -> None:
    """A pit's back wall lies at or below its near rim (paper N Fig. 5): never structure."""
    pits = [Hole.ahead(8.0, 1.0, 1.0, 1.0), Hole.ahead(14.0, 1.5, 0.6, 0.5)]
    assert not StructureDetector(grid=GRID).update(rig(holes=pits), Pose()).any()
    assert not StructureDetector(grid=GRID).update(rig(), Pose()).any()


def test_returns_above_the_vehicle_are_not_obstacles() -> None:
    """Of a 3.2 m wall on flat ground (ground level 0), only the returns from 0.25 m (the ROI's
    ground tolerance) to max_height_m count: branches higher up pass over the vehicle."""
    wall = Block(x0_m=-1.0, x1_m=1.0, y0_m=12.0, y1_m=12.4, height_m=3.2)
    cloud = hdl64_scan(blocks=[wall]).points_vehicle
    ground = build_ground_map([cloud], 20.0, RoiConfig())
    pts = structure_points(ground, cloud, 2.5)
    assert len(pts) and pts[:, 2].min() > 0.25 and pts[:, 2].max() <= 2.5
    tall = structure_points(ground, cloud, 4.0)  # the HDL-64's top laser (+2 deg) meets it at 2.6 m
    assert tall[:, 2].max() > 2.5


def test_the_ground_map_of_paper_n_detector_gives_the_same_grid() -> None:
    """Passing the negative detector's ground map (as the envs do) equals building it here."""
    scans = rig(holes=[Hole.ahead(8.0, 1.0, 1.0, 1.0)], blocks=[ROCK])
    detection = NegativeObstacleDetector().update(scans, Pose())
    own = StructureDetector(grid=GRID).update(scans, Pose())
    shared = StructureDetector(grid=GRID).update(scans, Pose(), detection.ground_map)
    assert own.any() and np.array_equal(own, shared)


def test_held_structure_follows_the_pose_and_expires() -> None:
    """With ``hold_s`` the rock stays marked after a frame without returns, 2 m nearer once the
    vehicle has moved 2 m, and is gone after the hold; ``reset`` forgets it."""
    seen = rig(blocks=[ROCK])
    empty = {k: dataclasses.replace(s, ranges_m=np.full(s.shape, np.nan)) for k, s in seen.items()}
    later = {k: dataclasses.replace(s, timestamp_s=0.3) for k, s in empty.items()}
    expired = {k: dataclasses.replace(s, timestamp_s=0.9) for k, s in empty.items()}
    det = StructureDetector(StructureConfig(hold_s=0.5), grid=GRID)
    first = det.update(seen, Pose())
    moved = Pose(y=2.0)  # 2 m along the world's +Y, the vehicle's forward axis at yaw 0
    held = det.update(later, moved)
    assert held.sum() == first.sum()
    nearer = dataclasses.replace(ROCK, y0_m=ROCK.y0_m - 2.0, y1_m=ROCK.y1_m - 2.0)
    assert held[footprint(GRID, nearer)].all() and not held[footprint(GRID, ROCK)].any()
    assert np.array_equal(det.update({}, moved), held)  # a frame with no scans (dropout) keeps them
    assert not det.update(expired, moved).any()
    det.update(seen, Pose())
    det.reset()
    assert not det.update(later, moved).any()
    # Per frame (the default): nothing held.
    per_frame = StructureDetector(grid=GRID)
    per_frame.update(seen, Pose())
    assert not per_frame.update(later, moved).any()


def test_point_hold_drops_frames_stamped_later_than_the_scan() -> None:
    """A restart without reset (time running again from 0) does not bring old frames back."""
    hold = PointHold(5.0)
    hold.recall_and_keep(np.ones((3, 3)), Pose(), 10.0)
    assert len(hold.recall_and_keep(np.zeros((0, 3)), Pose(), 11.0)) == 3
    assert len(hold.recall_and_keep(np.zeros((0, 3)), Pose(), 0.0)) == 0


def test_no_returns_and_no_scans_give_an_empty_grid() -> None:
    scans = rig()
    empty = {k: dataclasses.replace(s, ranges_m=np.full(s.shape, np.nan)) for k, s in scans.items()}
    det = StructureDetector(StructureConfig(hold_s=1.0), grid=GRID)
    assert not det.update(empty, Pose()).any()
    assert not det.update({}, Pose()).any()


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("hold_s", -1.0),
        ("hold_s", math.nan),
        ("max_height_m", 0.1),
        ("max_height_m", math.inf),
        ("max_range_m", 0.0),
    ],
)
def test_bad_config_is_refused(field, value) -> None:
    with pytest.raises(ValueError, match=field):
        StructureConfig(**{field: value})


def test_bad_input_is_refused() -> None:
    det = StructureDetector(grid=GRID)
    with pytest.raises(ValueError, match="pose"):
        det.update(rig(), (0.0, 0.0))
    with pytest.raises(ValueError, match="StructuredScan"):
        det.update({"hdl64": np.zeros((64, 10))}, Pose())
    with pytest.raises(ValueError, match="hold_s"):
        PointHold(math.nan)
