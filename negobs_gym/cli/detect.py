"""``negobs detect``: paper N's negative-obstacle detector on recorded LiDAR files.

Reads each FILE (see :mod:`negobs_gym.detector.io`), runs one
:class:`~negobs_gym.detector.NegativeObstacleDetector` over all frames in order (a bag or pcap is a
sequence, several files are one sequence) and writes, for frame ``n`` of the sequence,
``<n>_<stem>_<frame>.json`` (this frame's pairs, the fused pairs, the obstacles, the grid's occupied
cells, and the cells of the structure channel: returns above paper N's ground map, walls, vehicles,
rocks; :mod:`negobs_gym.detector.structure`) and ``<n>_<stem>_<frame>.png`` (top-down: points
coloured by height, structure cells, pairs and outlines drawn), plus ``summary.json``; every file
is written atomically.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from negobs_gym.cli.common import non_negative_float, positive_float
from negobs_gym.core.files import write_atomic

if TYPE_CHECKING:
    from collections.abc import Iterator

    from negobs_gym.detector.io import PoseTrack, RecordedFrame, ScanSetup
    from negobs_gym.detector.io.tf import TransformChain, TransformTree

log = logging.getLogger(__name__)
#: ``--tf``: warn when the tree mounts the cloud's frame turned by more than this from the
#: ``--sensor`` mounting (the detector's ground and features assume that mounting) [deg]
MOUNT_TOLERANCE_DEG = 1.0
#: ``--mount-from-tf``: warn when the tree's mounting is turned by more than this from the
#: ``--sensor`` one, i.e. belongs to the other detector path (upright §3.1 or rolled 90 deg §3.2) [deg]
PATH_TOLERANCE_DEG = 30.0


@dataclass(frozen=True)
class RecordedSensor:
    """A sensor ``--sensor`` can name: column width, fallback elevation table, and the paper N rig
    mount whose extrinsics it takes (``hdl64``: upright on the roof; ``hdl32_left/right``: rolled
    90 deg on the sides). Upright sensors feed the detector's HDL-64 path, rolled ones its HDL-32 path."""

    help: str
    azimuth_resolution_deg: float
    elevation_deg: tuple[float, ...]  # fallback table for clouds without ring (empty: ring needed)
    mount: str = "hdl64"


def recorded_sensors() -> dict[str, RecordedSensor]:
    """The sensors ``--sensor`` offers, by name."""
    from negobs_gym.sensors.models import hdl32e, hdl64e_s2

    h64, h32 = hdl64e_s2().elevation_deg, hdl32e().elevation_deg
    return {
        "hdl64": RecordedSensor("HDL-64E S2 upright (default)", 0.09, h64),
        "hdl32": RecordedSensor("HDL-32E upright", 0.16, h32),
        "hdl32-left": RecordedSensor("HDL-32E rolled 90 deg, left side", 0.16, h32, "hdl32_left"),
        "hdl32-right": RecordedSensor("HDL-32E rolled 90 deg, right side", 0.16, h32, "hdl32_right"),
        # VLP-16 datasheet: 16 lasers -15..+15 deg in 2 deg steps, 0.2 deg at 10 Hz
        "vlp16": RecordedSensor("VLP-16 upright", 0.2, tuple(float(v) for v in np.arange(-15.0, 16.0, 2.0))),
        # VLP-32C: 0.2 deg at 10 Hz; its lasers are not evenly spaced, so files need a ring field
        "vlp32c": RecordedSensor("VLP-32C upright (files need a ring field)", 0.2, ()),
    }


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``detect`` command."""
    parser = subparsers.add_parser(
        "detect",
        help="paper N's negative-obstacle detector on recorded scans; writes PNG + JSON per frame",
        description="Runs paper N's negative-obstacle detector on recorded LiDAR files and writes, "
        "per frame, a top-down PNG (points coloured by height, this frame's pairs, fused pairs, "
        "obstacle outlines, grid cells, structure cells) and a JSON with the grid, the pairs, the "
        "obstacles and the structure cells (returns standing 0.25-2.5 m above paper N's ground map: "
        "walls, vehicles, rocks). "
        "Formats: .bin (KITTI float32 x,y,z,intensity; --bin-fields xyzir for a ring column), .pcd, "
        ".pcap (raw Velodyne), ROS 1 .bag / ROS 2 bags with sensor_msgs/PointCloud2; .pcd, bags and "
        ".pcap need `pip install negobs_gym[real]`. Files are read in the ROS/Velodyne frame "
        "(x forward, y left, z up). All FILEs form one sequence; a bag or pcap is a sequence. "
        "Without --poses, --poses-topic, --tf, --kitti-poses or --kitti-oxts every frame is taken as "
        "standing still at the same place, so multi-frame fusion accumulates evidence only for a "
        "vehicle that did not move.",
    )
    parser.add_argument("files", nargs="+", metavar="FILE", help="recorded scans, read in order")
    parser.add_argument("--out", required=True, help="folder for the PNG and JSON files")
    parser.add_argument(
        "--sensor",
        choices=tuple(recorded_sensors()),
        default="hdl64",
        help="sensor model and mounting: "
        + "; ".join(f"{name}: {spec.help}" for name, spec in recorded_sensors().items())
        + ". Upright sensors use the detector's HDL-64 path (paper N §3.1), rolled ones its HDL-32 "
        "path (§3.2)",
    )
    parser.add_argument(
        "--height",
        type=positive_float,
        default=None,
        help="sensor origin above the ground [m] (default: the paper N rig's, 2.2 m for the roof "
        "sensor, 2.0 m for the side HDL-32s)",
    )
    parser.add_argument(
        "--bin-fields", choices=("xyzi", "xyzir"), default="xyzi", help=".bin layout (default: %(default)s)"
    )
    parser.add_argument("--topic", default=None, help="PointCloud2 topic of a bag with several")
    parser.add_argument(
        "--azimuth-resolution",
        type=positive_float,
        default=None,
        metavar="DEG",
        help="range-image column width [deg] (default: the sensor's)",
    )
    poses = parser.add_mutually_exclusive_group()
    poses.add_argument(
        "--poses",
        default=None,
        metavar="CSV",
        help="the vehicle's pose at each frame of the sequence, in order: a CSV whose header names "
        "x,y,z,roll,pitch,yaw (m, rad, ROS axes: x forward, y left, yaw from the world x axis), so "
        "that the multi-frame fusion follows a moving vehicle",
    )
    poses.add_argument(
        "--poses-topic",
        default=None,
        metavar="TOPIC",
        help="bags only: take each frame's pose from this nav_msgs/Odometry or geometry_msgs/"
        "PoseStamped topic of the same bag, interpolated at the frame's time (--stamps)",
    )
    poses.add_argument(
        "--tf",
        type=tf_frames,
        default=None,
        metavar="FIXED:BODY",
        help="bags only: take each frame's pose from the bag's /tf and /tf_static, the chain from "
        "frame FIXED to the vehicle's frame BODY (e.g. odom:base_link or map:base_link), each edge "
        "interpolated at the frame's time (--stamps)",
    )
    poses.add_argument(
        "--kitti-poses",
        default=None,
        metavar="TXT",
        help="a KITTI odometry poses/NN.txt (the camera's 3x4 pose per frame), with --kitti-calib: "
        "the vehicle's pose at each frame, from the Velodyne's pose less its mounting",
    )
    poses.add_argument(
        "--kitti-oxts",
        default=None,
        metavar="DIR",
        help="a KITTI raw drive's oxts folder (one GPS/IMU fix per frame), with --kitti-calib "
        "calib_imu_to_velo.txt: the vehicle's pose at each frame, from the IMU's pose and the "
        "calibration, less the sensor's mounting; positions relative to the first frame",
    )
    parser.add_argument(
        "--kitti-calib",
        default=None,
        metavar="TXT",
        help="with --kitti-poses the sequence's calib.txt, whose Tr line takes the Velodyne to the "
        "camera; with --kitti-oxts the date folder's calib_imu_to_velo.txt",
    )
    parser.add_argument(
        "--stamps",
        choices=("record", "header"),
        default="record",
        help="bags only: time clouds and poses by when the bag recorded them (default) or by their "
        "header stamps, the sensor's and the odometry's own clocks without the transport's latency",
    )
    parser.add_argument(
        "--max-pose-gap",
        type=non_negative_float,
        default=0.1,
        metavar="S",
        help="--poses-topic and --tf: how far [s] a cloud may lie outside a pose topic's or a timed "
        "tf edge's span and take its first or last pose (default: %(default)s; a localiser's "
        "map -> odom at 1 Hz may need 1)",
    )
    parser.add_argument(
        "--mount-from-tf",
        action="store_true",
        help="with --tf: take the sensor's mounting (rotation and position on the vehicle) from the "
        "tree's chain from BODY to the clouds' frame_id at each bag's first cloud, instead of "
        "--sensor's and --height; --sensor still picks the sensor model and detector path",
    )
    parser.add_argument(
        "--body-height",
        type=non_negative_float,
        default=0.0,
        metavar="M",
        help="with --tf: BODY's origin above the ground [m]; the vehicle's pose and frame are taken "
        "that far below BODY (default: %(default)s, BODY on the ground as base_footprint; "
        "base_link usually sits at the rear axle)",
    )
    parser.add_argument(
        "--tighten-pairs",
        action="store_true",
        help="move a fused pair's near edge to the closer frames' (FusionConfig.tighten_on_match; "
        "not in paper N; useful with --poses)",
    )
    parser.add_argument("--no-png", action="store_true", help="JSON only (faster on long bags)")
    parser.set_defaults(handler=run)


def tf_frames(text: str) -> tuple[str, str]:
    """``FIXED:BODY`` as two frame names (argparse type of ``--tf``)."""
    parts = text.split(":")
    if len(parts) != 2 or not all(part.strip("/ ") for part in parts):
        raise argparse.ArgumentTypeError(
            f"want two frame names FIXED:BODY (e.g. odom:base_link), got {text!r}"
        )
    return parts[0].strip(), parts[1].strip()


def _frames_and_tracks(
    args: argparse.Namespace, setup: ScanSetup
) -> Iterator[tuple[RecordedFrame, PoseTrack | TransformChain | None]]:
    """Every frame of ``args.files`` in order, each with its bag's pose track (``--poses-topic``
    or ``--tf``, read once per bag; None otherwise). With ``--tf`` a bag's first frame is also
    checked against the mounting the detector assumes."""
    from negobs_gym.detector.io import read_recording
    from negobs_gym.detector.io.bags import bag_pose_track, bag_transform_tree

    for path in args.files:
        track: PoseTrack | TransformChain | None = None
        tree: TransformTree | None = None
        if args.poses_topic:
            track = bag_pose_track(path, args.poses_topic, stamps=args.stamps, max_gap_s=args.max_pose_gap)
        elif args.tf:
            tree = bag_transform_tree(path, stamps=args.stamps)
            track = tree.chain(*args.tf, max_gap_s=args.max_pose_gap, body_height_m=args.body_height)
        frames = read_recording(path, setup, bin_layout=args.bin_fields, topic=args.topic, stamps=args.stamps)
        mounting: tuple[np.ndarray, np.ndarray] | None = None
        for k, frame in enumerate(frames):
            if tree is not None and k == 0:
                if args.mount_from_tf:
                    mounting = _tf_mounting(tree, args, frame)
                if frame.frame_id:
                    _check_mounting(tree, args.tf[1], frame, setup, args)
            if mounting is not None:
                scan = dataclasses.replace(frame.scan, rotation=mounting[0], translation_m=mounting[1])
                frame = dataclasses.replace(frame, scan=scan)
            yield frame, track


def _tf_mounting(
    tree: TransformTree, args: argparse.Namespace, frame: RecordedFrame
) -> tuple[np.ndarray, np.ndarray]:
    """``--mount-from-tf``: the mounting of the bag's clouds on the vehicle at its first cloud."""
    from negobs_gym.detector.io.tf import sensor_mounting
    from negobs_gym.errors import ScanError

    if not frame.frame_id:
        raise ScanError(f"{frame.source}: the clouds name no frame_id, so --mount-from-tf cannot find them")
    try:
        rotation, translation = sensor_mounting(
            tree,
            args.tf[1],
            frame.frame_id,
            frame.scan.timestamp_s,
            body_height_m=args.body_height,
            max_gap_s=args.max_pose_gap,
        )
    except ScanError as error:
        raise ScanError(f"--mount-from-tf: {error}") from error
    log.info(
        "%s: the clouds' frame %s is mounted at %s m (vehicle X right, Y forward, Z up) by the bag's tf",
        frame.source,
        frame.frame_id,
        np.round(translation, 3).tolist(),
    )
    return rotation, translation


def _check_mounting(
    tree: TransformTree, body: str, frame: RecordedFrame, setup: ScanSetup, args: argparse.Namespace
) -> None:
    """Warn when the bag's tf mounts the cloud's frame on ``body`` turned from the ``--sensor``
    mounting: by more than :data:`MOUNT_TOLERANCE_DEG` where the detector assumes that mounting,
    by more than :data:`PATH_TOLERANCE_DEG` where it takes the tf's (``--mount-from-tf``), as the
    ``--sensor`` path then reads a sensor mounted as the other path expects."""
    from negobs_gym.detector.io.tf import mounting_difference_deg

    time_s = frame.scan.timestamp_s
    angle = mounting_difference_deg(tree, body, frame.frame_id, setup, time_s, max_gap_s=args.max_pose_gap)
    if angle is None or angle <= (PATH_TOLERANCE_DEG if args.mount_from_tf else MOUNT_TOLERANCE_DEG):
        return
    if args.mount_from_tf:
        consequence = (
            "mounting, whose detector path (upright or rolled) reads it; pick the --sensor mounted nearest"
        )
    else:
        consequence = (
            "mounting the detector assumes; its ground and features will be off "
            "(--mount-from-tf takes the tf's)"
        )
    log.warning(
        "%s: the bag's tf (%s -> %s) turns the cloud's frame %.1f deg from the --sensor %s %s",
        frame.source,
        body,
        frame.frame_id,
        angle,
        setup.sensor,
        consequence,
    )


def _check_tf_options(args: argparse.Namespace) -> None:
    """``--mount-from-tf`` and ``--body-height`` need ``--tf``; ``--height`` is the tree's then."""
    from negobs_gym.errors import ScanError

    if args.tf is None and (args.mount_from_tf or args.body_height):
        raise ScanError("--mount-from-tf and --body-height go with --tf FIXED:BODY")
    if args.mount_from_tf and args.height is not None:
        raise ScanError("--height and --mount-from-tf both set the sensor's height: give one")


def scan_setup(args: argparse.Namespace) -> ScanSetup:
    """The :class:`ScanSetup` for ``--sensor``, ``--height`` and ``--azimuth-resolution``."""
    from negobs_gym.detector.io import ScanSetup
    from negobs_gym.sensors.rigs import paper_n_rig

    spec = recorded_sensors()[args.sensor]
    mount = next(m for m in paper_n_rig().mounts if m.name == spec.mount)
    x, y, z = mount.translation_m
    return ScanSetup(
        sensor=mount.name,
        azimuth_resolution_deg=args.azimuth_resolution or spec.azimuth_resolution_deg,
        elevation_rad=tuple(math.radians(v) for v in spec.elevation_deg),
        rotation=tuple(tuple(float(v) for v in row) for row in mount.rotation_matrix),
        translation_m=(x, y, z if args.height is None else args.height),
    )


def run(args: argparse.Namespace) -> int:
    """Detect on every frame of ``args.files``; writes the per-frame files and ``summary.json``."""
    from tqdm import tqdm

    from negobs_gym.cli.detect_report import detection_record, plot_detection
    from negobs_gym.core.pose import Pose
    from negobs_gym.detector import (
        FusionConfig,
        NegativeDetectorConfig,
        NegativeObstacleDetector,
        StructureDetector,
    )
    from negobs_gym.detector.io import read_poses_csv
    from negobs_gym.errors import ScanError

    _check_tf_options(args)
    setup = scan_setup(args)
    out = Path(args.out)
    poses = read_poses_csv(args.poses) if args.poses else None
    kitti = args.kitti_poses or args.kitti_oxts
    if (kitti is None) != (args.kitti_calib is None):
        raise ScanError(
            "--kitti-calib goes with --kitti-poses (a sequence's poses and its calib.txt) or "
            "--kitti-oxts (a raw drive's oxts folder and calib_imu_to_velo.txt), and they with it"
        )
    if args.kitti_poses:
        from negobs_gym.detector.io.kitti import kitti_vehicle_poses, read_kitti_poses, read_kitti_velo_to_cam

        cameras, velo_to_cam = read_kitti_poses(args.kitti_poses), read_kitti_velo_to_cam(args.kitti_calib)
        poses = kitti_vehicle_poses(cameras, velo_to_cam, setup)
    elif args.kitti_oxts:
        from negobs_gym.detector.io.kitti import (
            kitti_oxts_vehicle_poses,
            read_kitti_imu_to_velo,
            read_kitti_oxts,
        )

        fixes, imu_to_velo = read_kitti_oxts(args.kitti_oxts), read_kitti_imu_to_velo(args.kitti_calib)
        poses = kitti_oxts_vehicle_poses(fixes, imu_to_velo, setup)
    poses_file = args.poses or kitti
    detector = NegativeObstacleDetector(
        NegativeDetectorConfig(fusion=FusionConfig(tighten_on_match=args.tighten_pairs))
    )
    structure = StructureDetector(grid=detector.config.grid)
    summary = []

    frames = _frames_and_tracks(args, setup)
    bar = tqdm(frames, desc="negobs detect", unit="frame", disable=None)
    for n, (frame, track) in enumerate(bar):
        if poses is not None and n >= len(poses):
            raise ScanError(f"{poses_file}: {len(poses)} poses, but the recording has more frames")
        if track is not None:
            try:
                pose = track.at(frame.scan.timestamp_s)
            except ScanError as error:  # name the frame: a cloud outside the odometry's span
                raise ScanError(f"{frame.source}, frame {frame.index}: {error}") from error
        else:
            pose = poses[n] if poses is not None else Pose()
        scans = {frame.scan.sensor: frame.scan}
        detection = detector.update(scans, pose)
        cells = structure.update(scans, pose, detection.ground_map)
        stem = f"{n:05d}_{Path(frame.source).stem}_{frame.index:04d}"  # n: the same file may repeat
        given = poses is not None or track is not None
        record = detection_record(frame, detection, args.sensor, cells, pose if given else None)
        write_atomic(out / f"{stem}.json", lambda tmp, r=record: tmp.write_text(json.dumps(r, indent=1)))
        if not args.no_png:
            write_atomic(
                out / f"{stem}.png", lambda tmp, f=frame, d=detection, c=cells: plot_detection(f, d, c, tmp)
            )
        summary.append(
            {
                "frame": stem,
                **{k: record[k] for k in ("n_points", "n_frame_pairs", "n_obstacles")},
                "n_structure_cells": len(record["structure_cells"]),
            }
        )
        log.debug("%s: %d pairs, %d obstacles", stem, record["n_frame_pairs"], record["n_obstacles"])
    write_atomic(out / "summary.json", lambda tmp: tmp.write_text(json.dumps(summary, indent=1)))
    if poses is not None and len(poses) > len(summary):
        log.warning(
            "%s: %d poses for %d frames; the last %d unused",
            poses_file,
            len(poses),
            len(summary),
            len(poses) - len(summary),
        )
    log.info(
        "negobs detect: %d frames, %d obstacles in the last, written to %s",
        len(summary),
        summary[-1]["n_obstacles"] if summary else 0,
        out,
    )
    return 0
