"""Rings from the point order of generated HDL-64E files in KITTI's layouts; the table fallback warns.

The clouds are synthesised laser by laser with the HDL-64E S2 table the package ships, as KITTI's
tools write them: each laser's sweep one turn from straight ahead (object set ``velodyne/*.bin``,
raw set ``velodyne_points/data/*.bin``), so that the +-180 deg seam behind cuts every laser, the
object detectors' camera-view crop of the object set (``velodyne_reduced``; also with a dark car
ahead that returns nothing to every 4th laser just after the origin), and a revolution cut
just before the seam, so that every laser has its points at the start and the end of its ring,
with a few lasers firing 1.5 deg early or late. Each laser sits a few cm above the sensor origin, as a real
HDL-64E's do, so its returns' elevation seen from the origin moves with their range. No KITTI data
is used (its licence is non-commercial). Refused: a shuffled cloud, and a grey image written as
``x, y, z, intensity`` points (pixel column, row, grey, grey), as one public "velodyne" repository's
example files are.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from negobs_gym.detector.io import ScanSetup, read_bin
from negobs_gym.detector.loaders import PointOrderConfig, assign_rings, ros_to_sensor_frame
from negobs_gym.errors import ConfigError
from negobs_gym.sensors.calibration import HDL64E_S2_SZTAKI_VERT_CORRECTION_RAD

TABLE = np.asarray(HDL64E_S2_SZTAKI_VERT_CORRECTION_RAD)
SETUP = ScanSetup(elevation_rad=tuple(TABLE))
HEIGHT_M = 1.73  # KITTI's Velodyne above the road
STEP_DEG = 0.18  # KITTI's HDL-64E at 10 Hz: 2,000 returns per laser and turn
MAX_RANGE_M = 120.0


def _cast(elevation: float, azimuth_deg: np.ndarray, lift_m: float) -> np.ndarray:
    """ROS-frame returns of one laser (origin ``lift_m`` above the sensor origin) off a road with a
    wall 7 m to the left, a wall 5 m to the right and a box ahead; NaN where nothing is hit."""
    az = np.radians(azimuth_deg)
    d = np.column_stack(
        [np.cos(elevation) * np.cos(az), np.cos(elevation) * np.sin(az), np.full(az.size, np.sin(elevation))]
    )
    t = np.full(az.size, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for hit in (
            np.where(d[:, 2] < 0, (-HEIGHT_M - lift_m) / d[:, 2], np.inf),  # road
            np.where(d[:, 1] > 0, 7.0 / d[:, 1], np.inf),  # left wall
            np.where(d[:, 1] < 0, -5.0 / d[:, 1], np.inf),  # right wall
        ):
            t = np.minimum(t, hit)
        box = np.where(d[:, 0] > 0, 12.0 / d[:, 0], np.inf)  # a box's face 12 m ahead, 1 m wide
        y_box = box * d[:, 1]
        z_box = lift_m + box * d[:, 2]
        on_box = (np.abs(y_box - 1.0) < 0.5) & (z_box > -HEIGHT_M) & (z_box < -HEIGHT_M + 1.5)
        t = np.where(on_box, np.minimum(t, box), t)
    t[t > MAX_RANGE_M] = np.nan
    p = t[:, None] * d
    p[:, 2] += lift_m
    return p


def _kitti_cloud(layout: str, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4) float32 x, y, z, intensity in ``layout`` and the (N,) laser each point came from."""
    rng = np.random.default_rng(seed)
    order = np.argsort(-TABLE)  # KITTI stores the lasers top down
    # the laser_id 0-31 block above the 32-63 block, each laser within +-1 cm of its block's height
    lift = np.where(np.arange(TABLE.size) < 32, 0.20, 0.12) + rng.uniform(-0.01, 0.01, TABLE.size)
    offset = np.zeros(TABLE.size)  # by file position: a few lasers fire 1.5 deg early or late
    if layout == "seam":
        offset[[5, 20, 41]], offset[[12, 33, 50]] = -1.5, 1.5
    phase = rng.uniform(0.0, STEP_DEG, TABLE.size)  # each laser's first firing after the cut
    clouds, lasers = [], []
    for k, laser in enumerate(order):
        if layout == "seam":  # the revolution starts 0.7 deg before the seam behind, so every
            # laser's ring is split at the seam: a few returns first, the rest after the seam
            az = 179.3 + offset[k] + phase[laser] + np.arange(0.0, 360.0 - STEP_DEG, STEP_DEG)
        else:  # KITTI: every laser's sweep from straight ahead, one turn counter-clockwise
            az = phase[laser] + np.arange(0.0, 360.0 - STEP_DEG, STEP_DEG)
        az = az + rng.normal(0.0, 0.002, az.size)
        p = _cast(TABLE[laser], az, lift[laser])
        keep = np.isfinite(p).all(axis=1) & (rng.random(az.size) > 0.03)  # no return, dropped returns
        if layout in ("reduced", "reduced_dark"):  # the camera's view: +-45 deg ahead
            keep &= (p[:, 0] > 0) & (np.abs(np.arctan2(p[:, 1], p[:, 0])) < np.radians(45.0))
        if layout == "reduced_dark" and k % 4 == 1:  # a dark car ahead-left returns nothing to
            keep &= (az < 1.5) | (az > 40.0)  # every 4th laser: its start lies just before the crop
        clouds.append(p[keep])
        lasers.append(np.full(int(keep.sum()), k))
    xyz = np.concatenate(clouds)
    cloud = np.column_stack([xyz, rng.random(len(xyz))]).astype(np.float32)
    return cloud, np.concatenate(lasers)


@pytest.mark.parametrize(
    ("layout", "name"),
    [
        ("object", "velodyne/000000.bin"),
        ("raw", "velodyne_points/data/0000000000.bin"),
        ("reduced", "velodyne_reduced/000000.bin"),
        ("reduced_dark", "velodyne_reduced/000008.bin"),
        ("seam", "velodyne_points/data/0000000001.bin"),
    ],
)
def test_rings_from_the_point_order_are_the_generating_lasers(tmp_path, layout, name):
    cloud, laser = _kitti_cloud(layout, seed=len(layout))
    path = tmp_path / name
    path.parent.mkdir(parents=True)
    cloud.tofile(path)
    frame = read_bin(path, SETUP)
    assert frame.ring_source == "point_order"
    rings = assign_rings(ros_to_sensor_frame(cloud[:, :3].astype(np.float64)), TABLE)
    assert rings.source == "point_order"
    np.testing.assert_array_equal(rings.ring, np.unique(laser, return_inverse=True)[1])
    assert frame.scan.shape[0] == np.unique(laser).size


def test_the_seam_layout_has_lasers_split_at_the_start_and_end_of_their_ring():
    """The seam case tested above is the hard one: lasers whose first points lie before the seam."""
    cloud, laser = _kitti_cloud("seam", seed=4)
    az = np.degrees(np.arctan2(cloud[:, 1], cloud[:, 0]))
    split = [k for k in np.unique(laser) if np.abs(np.diff(az[laser == k])).max() > 180.0]
    assert len(split) > 40


def test_the_seam_cut_lasers_are_missed_by_a_seam_only_cut():
    """Cutting at the seam alone (the rule before KITTI's layout was read) gets the object layout
    wrong: every laser of a sweep that starts straight ahead crosses the seam."""
    cloud, laser = _kitti_cloud("object", seed=6)
    az = np.arctan2(cloud[:, 1], cloud[:, 0])
    seam_cut = np.concatenate([[0], np.cumsum(np.abs(np.diff(az)) > np.pi)])
    assert not np.array_equal(seam_cut, np.unique(laser, return_inverse=True)[1])
    rings = assign_rings(ros_to_sensor_frame(cloud[:, :3].astype(np.float64)), TABLE)
    np.testing.assert_array_equal(rings.ring, np.unique(laser, return_inverse=True)[1])


def test_a_cropped_sweeps_gap_is_no_laser_start():
    """In the camera-view crop a laser with few returns after the origin (mmdet3d's demo frame
    000008.bin) reaches the crop's gap within the boundary window: its 270 deg jump forward reads
    as 90 deg back and, taken for a laser starting early, split the laser at the gap."""
    cloud, laser = _kitti_cloud("reduced_dark", seed=9)
    xyz = ros_to_sensor_frame(cloud[:, :3].astype(np.float64))
    truth = np.unique(laser, return_inverse=True)[1]
    np.testing.assert_array_equal(assign_rings(xyz, TABLE).ring, truth)
    every_step_back = PointOrderConfig(max_offset_step_deg=179.0)
    assert not np.array_equal(assign_rings(xyz, TABLE, config=every_step_back).ring, truth)


def test_fallback_to_the_table_warns_naming_the_file(tmp_path, caplog):
    cloud, _ = _kitti_cloud("object", seed=2)
    path = tmp_path / "shuffled.bin"
    cloud[np.random.default_rng(3).permutation(len(cloud))].tofile(path)
    with caplog.at_level(logging.WARNING, logger="negobs_gym.detector.loaders"):
        frame = read_bin(path, SETUP)
    assert frame.ring_source == "elevation_table"
    (record,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert str(path) in record.getMessage()
    assert "elevation-table" in record.getMessage()


def _image_as_points(width: int, height: int, seed: int) -> np.ndarray:
    """(N, 4) float32 points of a grey image written as a Processing sketch for Velodyne-style
    ``.bin`` files writes it (n1ckfg/pointcloud_velodyne's ``data/example002.bin``): pixel column,
    row, grey, grey, row by row, pixels of grey 0 left out."""
    rng = np.random.default_rng(seed)
    grey = np.clip(rng.normal(120.0, 60.0, (height, width)), 0, 255).round()
    row, col = np.nonzero(grey > 0)
    return np.column_stack([col, row, grey[row, col], grey[row, col]]).astype(np.float32)


def test_an_image_written_as_points_is_refused_and_the_warning_says_it_fits_no_laser(tmp_path, caplog):
    """An image's rows sweep like lasers, 640 points a row with a jump back at its end: the order
    must still be refused (hundreds of rows, elevations far above the HDL-64E's), and the warning
    says how far the points lie off the table."""
    cloud = _image_as_points(640, 120, seed=7)
    path = tmp_path / "velodyne_points" / "data" / "example002.bin"
    path.parent.mkdir(parents=True)
    cloud.tofile(path)
    xyz = ros_to_sensor_frame(cloud[:, :3].astype(np.float64))
    elevation = np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    outside = np.mean((elevation < np.degrees(TABLE.min())) | (elevation > np.degrees(TABLE.max())))
    assert outside > 0.9  # the generated image is what it should be: almost no point fits a laser
    with caplog.at_level(logging.WARNING, logger="negobs_gym.detector.loaders"):
        frame = read_bin(path, SETUP)
    assert frame.ring_source == "elevation_table"
    (record,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    message = record.getMessage()
    assert str(path) in message and "lasers found, the table has 64" in message
    assert f"{100 * outside:.0f} % of the points lie outside the table's elevations" in message


def test_scan_setup_point_order_thresholds_reach_the_ring_recovery(tmp_path, caplog):
    """A KITTI-layout file is ringed by its order with the default thresholds and refused when the
    setup asks for cuts stepping 50 laser spacings in elevation."""
    cloud, _ = _kitti_cloud("raw", seed=8)
    path = tmp_path / "0000000008.bin"
    cloud.tofile(path)
    assert read_bin(path, SETUP).ring_source == "point_order"
    strict = ScanSetup(elevation_rad=tuple(TABLE), point_order=PointOrderConfig(min_cut_step_spacings=50.0))
    with caplog.at_level(logging.WARNING, logger="negobs_gym.detector.loaders"):
        assert read_bin(path, strict).ring_source == "elevation_table"
    assert "median elevation step between lasers" in caplog.text


def test_the_point_order_warns_nothing(tmp_path, caplog):
    cloud, _ = _kitti_cloud("object", seed=5)
    path = tmp_path / "000005.bin"
    cloud.tofile(path)
    with caplog.at_level(logging.WARNING):
        assert read_bin(path, SETUP).ring_source == "point_order"
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


@pytest.mark.parametrize(
    "field",
    [
        "back_step_deg",
        "origin_step_deg",
        "neighbour_gap_deg",
        "min_cut_step_spacings",
        "max_laser_step_spacings",
        "max_offset_step_deg",
    ],
)
def test_point_order_config_refuses_a_bad_threshold(field):
    with pytest.raises(ConfigError, match=field):
        PointOrderConfig(**{field: -1.0})
