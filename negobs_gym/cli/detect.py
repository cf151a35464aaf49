"""``negobs detect``: paper N's negative-obstacle detector (and paper T's traversable-region
detector for a 4-layer LiDAR) on recorded LiDAR files.

Reads each FILE (see :mod:`negobs_gym.detector.io`), runs one
:class:`~negobs_gym.detector.NegativeObstacleDetector` over all frames in order (a bag or pcap is a
sequence, several files are one sequence) and writes, for frame ``n`` of the sequence,
``<n>_<stem>_<frame>.json`` (this frame's pairs, the fused pairs, the obstacles, the grid's occupied
cells, and the cells of the structure channel: returns above paper N's ground map, walls, vehicles,
rocks; :mod:`negobs_gym.detector.structure`) and ``<n>_<stem>_<frame>.png`` (top-down: points
coloured by height, structure cells, pairs and outlines drawn), plus ``summary.json``; every file
is written atomically. A LUX cloud (``--sensor lux``, or a ``--cloud`` topic) goes to one
:class:`~negobs_gym.detector.TraversableRegionDetector` instead: its boundaries, obstacles and
region in the JSON's ``traversable`` key and in the PNG.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from negobs_gym.cli.common import non_negative_float, positive_float, positive_int
from negobs_gym.core.files import write_atomic

if TYPE_CHECKING:
    from collections.abc import Iterator

    from negobs_gym.core.grid import GridSpec
    from negobs_gym.core.scan import StructuredScan
    from negobs_gym.detector.io import PoseTrack, RecordedFrame, ScanSetup
    from negobs_gym.detector.io.sync import SynchronisedFrames
    from negobs_gym.detector.io.tf import TransformChain, TransformTree
    from negobs_gym.eval.recorded import RecordedRecall

log = logging.getLogger(__name__)
#: ``--tf``: warn when the tree mounts the cloud's frame turned by more than this from the
#: ``--sensor`` mounting (the detector's ground and features assume that mounting) [deg]
MOUNT_TOLERANCE_DEG = 1.0
#: ``--mount-from-tf``: warn when the tree's mounting is turned by more than this from the
#: ``--sensor`` one, i.e. belongs to the other detector path (upright §3.1 or rolled 90 deg §3.2) [deg]
PATH_TOLERANCE_DEG = 30.0
#: ``--sensor`` when neither it nor ``--cloud`` is given
DEFAULT_SENSOR = "hdl64"
#: The detector input of paper T's 4-layer LiDAR (the mount of ``sensors.rigs.paper_t_rig``)
LUX_MOUNT = "lux"


@dataclass(frozen=True)
class CloudSpec:
    """One ``--cloud TOPIC:SENSOR[:HEIGHT]``: a bag topic, the ``--sensor`` it comes from, and its
    height above the ground [m] (None: the sensor's paper N rig mount, or the tf's)."""

    topic: str
    sensor: str
    height_m: float | None = None


@dataclass(frozen=True)
class RecordedSensor:
    """A sensor ``--sensor`` can name: column width, fallback elevation table, and the rig mount
    whose extrinsics it takes (paper N's ``hdl64``: upright on the roof, ``hdl32_left/right``:
    rolled 90 deg on the sides; paper T's ``lux``: 0.65 m up, pitched down 5.03 deg). Upright sensors feed
    paper N's HDL-64 path, rolled ones its HDL-32 path, the LUX paper T's traversable-region detector."""

    help: str
    azimuth_resolution_deg: float
    elevation_deg: tuple[float, ...]  # fallback table for clouds without ring (empty: ring needed)
    mount: str = "hdl64"
    columns_centred: bool = False  # a fixed-angle scanner: columns centred on its firing angles
    crop_columns: bool = False  # a field of view short of a revolution: the range image spans it only


def recorded_sensors() -> dict[str, RecordedSensor]:
    """The sensors ``--sensor`` offers, by name."""
    from negobs_gym.sensors.models import hdl32e, hdl64e_s2, ibeo_lux

    h64, h32, lux = hdl64e_s2().elevation_deg, hdl32e().elevation_deg, ibeo_lux()
    return {
        "hdl64": RecordedSensor("HDL-64E S2 upright (default)", 0.09, h64),
        "hdl32": RecordedSensor("HDL-32E upright", 0.16, h32),
        "hdl32-left": RecordedSensor("HDL-32E rolled 90 deg, left side", 0.16, h32, "hdl32_left"),
        "hdl32-right": RecordedSensor("HDL-32E rolled 90 deg, right side", 0.16, h32, "hdl32_right"),
        # VLP-16 datasheet: 16 lasers -15..+15 deg in 2 deg steps, 0.2 deg at 10 Hz
        "vlp16": RecordedSensor("VLP-16 upright", 0.2, tuple(float(v) for v in np.arange(-15.0, 16.0, 2.0))),
        # VLP-32C: 0.2 deg at 10 Hz; its lasers are not evenly spaced, so files need a ring field
        "vlp32c": RecordedSensor("VLP-32C upright (files need a ring field)", 0.2, ()),
        "lux": RecordedSensor(
            "IBEO LUX or SICK LD-MRS, 4 layers, on the front bumper 3.7 m ahead of the rear axle, "
            "0.65 m up, pitched down 5.03 deg (paper T; the envs' LUX)",
            lux.azimuth_resolution_deg,
            lux.elevation_deg,
            LUX_MOUNT,
            columns_centred=True,
            crop_columns=True,
        ),
        # SICK MRS1000 / MRS1104: 4 layers 2.5 deg apart (-2.5 .. +5 deg), 0.25 deg over 275 deg
        "mrs1000": RecordedSensor(
            "SICK MRS1000/MRS1104, 4 layers, at the LUX's mount (paper T)",
            0.25,
            (-2.5, 0.0, 2.5, 5.0),
            LUX_MOUNT,
            columns_centred=True,
            crop_columns=True,
        ),
    }


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``detect`` command."""
    parser = subparsers.add_parser(
        "detect",
        help="paper N's negative-obstacle detector (paper T's traversable region for a 4-layer "
        "LiDAR) on recorded scans; writes PNG + JSON per frame",
        description="Runs paper N's negative-obstacle detector on recorded LiDAR files (paper T's "
        "traversable-region detector on a 4-layer LiDAR's: --sensor lux) and writes, "
        "per frame, a top-down PNG (points coloured by height, this frame's pairs, fused pairs, "
        "obstacle outlines, grid cells, structure cells) and a JSON with the grid, the pairs, the "
        "obstacles and the structure cells (returns standing 0.25-2.5 m above paper N's ground map: "
        "walls, vehicles, rocks). "
        "Formats: .bin (KITTI float32 x,y,z,intensity; --bin-fields xyzir for a ring column), .pcd, "
        ".pcap (raw Velodyne), ROS 1 .bag / ROS 2 bags with sensor_msgs/PointCloud2; .pcd, bags and "
        ".pcap need `pip install negobs_gym[real]`. Files are read in the ROS/Velodyne frame "
        "(x forward, y left, z up). All FILEs form one sequence; a bag or pcap is a sequence. "
        "Without --poses, --poses-track, --poses-topic, --tf, --kitti-poses or --kitti-oxts every "
        "frame is taken as standing still at the same place, so multi-frame fusion accumulates "
        "evidence only for a vehicle that did not move.",
    )
    parser.add_argument("files", nargs="+", metavar="FILE", help="recorded scans, read in order")
    parser.add_argument("--out", required=True, help="folder for the PNG and JSON files")
    parser.add_argument(
        "--sensor",
        choices=tuple(recorded_sensors()),
        default=None,
        help="sensor model and mounting (default: hdl64): "
        + "; ".join(f"{name}: {spec.help}" for name, spec in recorded_sensors().items())
        + ". Upright sensors use paper N's HDL-64 path (§3.1), rolled ones its HDL-32 path (§3.2); "
        "lux and mrs1000 run paper T's traversable-region detector instead",
    )
    parser.add_argument(
        "--height",
        type=positive_float,
        default=None,
        help="sensor origin above the ground [m] (default: the rig's, 2.2 m for the roof sensor, "
        "2.0 m for the side HDL-32s, 0.65 m for the LUX)",
    )
    parser.add_argument(
        "--mount",
        type=ros_mount,
        default=None,
        metavar="X,Y,Z,ROLL,PITCH,YAW",
        help="the sensor's pose on the vehicle instead of the --sensor rig mount's: its origin [m] "
        "from the vehicle origin (rear axle centre on the ground) and its roll, pitch, yaw [deg], in "
        "ROS body axes (x forward, y left, z up; positive pitch tilts it nose down), as a tf edge "
        "from base_footprint would give them. --sensor still picks the model and detector path",
    )
    parser.add_argument(
        "--bin-fields", choices=("xyzi", "xyzir"), default="xyzi", help=".bin layout (default: %(default)s)"
    )
    parser.add_argument("--topic", default=None, help="PointCloud2 topic of a bag with several")
    parser.add_argument(
        "--cloud",
        type=cloud_spec,
        action="append",
        default=None,
        metavar="TOPIC:SENSOR[:HEIGHT]",
        help="bags only, repeated: a rig of LiDARs, one PointCloud2 topic each, in one detector "
        "update (paper N's rig: --cloud /top:hdl64 --cloud /left:hdl32-left --cloud "
        "/right:hdl32-right). SENSOR is a --sensor name, HEIGHT its origin above the ground [m] "
        "(default: its paper N rig mount's; --mount-from-tf takes the tf's). The first topic "
        "leads: each of its clouds makes an update, with every other topic's cloud nearest in "
        "time within --sync-window, brought to the lead's time by the vehicle's motion when the "
        "poses are timed (--poses-track, --poses-topic, --tf). Replaces --topic, --sensor and --height",
    )
    parser.add_argument(
        "--sync-window",
        type=non_negative_float,
        default=None,
        metavar="S",
        help="--cloud: how far [s] another topic's cloud may lie from the lead's and join its "
        "update (default: one revolution of a 10 Hz sensor, detector.io.sync.SYNC_WINDOW_S)",
    )
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
        "--poses-track",
        default=None,
        metavar="CSV",
        help="the vehicle's poses at times, e.g. an INS log: a CSV whose header names timestamp "
        "[s, on the frames' clock: a bag's --stamps, a pcap's capture time] and x,y,z,roll,pitch,yaw "
        "(as --poses), interpolated at each frame's time like --poses-topic (so --deskew and "
        "--cloud can use it)",
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
        "--deskew",
        action="store_true",
        help="bags and pcap with timed poses (--poses-track, --poses-topic, --tf): deskew each "
        "cloud, i.e. place each column's returns "
        "and the pairs found on them by the vehicle's motion between when the column was fired (the "
        "points' time field: time, t, offset_time, time_stamp or timestamp) and the cloud's time "
        "(the lead's with --cloud); the features read the scan as recorded. A 10 Hz revolution is "
        "0.7 m of travel at 25 km/h, and a cut ahead of the vehicle otherwise splits what lies there",
    )
    parser.add_argument(
        "--tighten-pairs",
        action="store_true",
        help="move a fused pair's near edge to the closer frames' (FusionConfig.tighten_on_match; "
        "not in paper N; useful with --poses)",
    )
    parser.add_argument(
        "--truth",
        default=None,
        metavar="JSON",
        help="surveyed negative obstacles of the drive, to measure paper N's recall on it: "
        '{"negative_obstacles": [{"name": ..., "outline_xy_m": [[x, y], ...]}, ...]}, ground outlines '
        "in the world frame of the poses (ROS axes; without poses the vehicle stands at the origin "
        "facing x). Each frame's JSON says which lie in the grid and which a detected obstacle "
        "overlaps; OUT/recall.json and recall.md give the recall by distance and in paper N's "
        "Table 7 layout, and the false alarms",
    )
    parser.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="DETECTOR.KEY=VALUE",
        help="change one detector setting, repeatable: negative.* (paper N, NegativeDetectorConfig: "
        "negative.fusion.prior=0.4, negative.hdl64.density_factor=0.5, negative.grid.ahead_m=40), "
        "traversable.* (paper T, TraversableConfig: traversable.vehicle_width_m=1.8), structure.* "
        "(StructureConfig); VALUE is TOML. The grid (negative.grid) is every detector's. OUT/config.json "
        "records the settings that ran",
    )
    pngs = parser.add_mutually_exclusive_group()
    pngs.add_argument("--no-png", action="store_true", help="JSON only (faster on long bags)")
    pngs.add_argument(
        "--png-every",
        type=positive_int,
        default=1,
        metavar="N",
        help="a PNG for every Nth frame only, the first included (a PNG takes ~0.25 s, the detector "
        "tens of ms: long recordings are drawn in a fraction of the time); every frame's JSON is written",
    )
    parser.set_defaults(handler=run)


def tf_frames(text: str) -> tuple[str, str]:
    """``FIXED:BODY`` as two frame names (argparse type of ``--tf``)."""
    parts = text.split(":")
    if len(parts) != 2 or not all(part.strip("/ ") for part in parts):
        raise argparse.ArgumentTypeError(
            f"want two frame names FIXED:BODY (e.g. odom:base_link), got {text!r}"
        )
    return parts[0].strip(), parts[1].strip()


def ros_mount(text: str) -> tuple[float, ...]:
    """``X,Y,Z,ROLL,PITCH,YAW`` as six finite numbers (argparse type of ``--mount``)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"want six numbers X,Y,Z,ROLL,PITCH,YAW (m, deg), got {text!r}")
    return values


def cloud_spec(text: str) -> CloudSpec:
    """``TOPIC:SENSOR[:HEIGHT]`` as a :class:`CloudSpec` (argparse type of ``--cloud``)."""
    parts = text.split(":")  # ROS names hold no colon
    sensors = recorded_sensors()
    if len(parts) not in (2, 3) or not parts[0].strip() or parts[1] not in sensors:
        raise argparse.ArgumentTypeError(
            f"want TOPIC:SENSOR[:HEIGHT] with SENSOR one of {', '.join(sensors)}, got {text!r}"
        )
    height = positive_float(parts[2]) if len(parts) == 3 else None
    return CloudSpec(parts[0].strip(), parts[1], height)


def _updates(
    args: argparse.Namespace, setups: dict[str, ScanSetup]
) -> Iterator[tuple[SynchronisedFrames, PoseTrack | TransformChain | None]]:
    """Every detector update of ``args.files`` in order, each with its bag's pose track
    (``--poses-topic`` or ``--tf``, read once per bag; None otherwise). ``setups`` by topic: one
    entry without ``--cloud`` (its key unused), the lead topic first with it. Each topic's first
    cloud of a bag is checked against (or with ``--mount-from-tf`` given) the tf tree's mounting."""
    from negobs_gym.detector.io import read_recording
    from negobs_gym.detector.io.bags import bag_clouds, bag_pose_track, bag_transform_tree
    from negobs_gym.detector.io.poses import read_pose_track_csv
    from negobs_gym.detector.io.recording import is_bag
    from negobs_gym.detector.io.sync import SYNC_WINDOW_S, synchronise
    from negobs_gym.errors import ScanError

    lead, *others = setups
    window_s = SYNC_WINDOW_S if args.sync_window is None else args.sync_window
    timed = read_pose_track_csv(args.poses_track, max_gap_s=args.max_pose_gap) if args.poses_track else None
    for path in args.files:
        track: PoseTrack | TransformChain | None = None
        tree: TransformTree | None = None
        if args.poses_track:
            if not (is_bag(path) or Path(path).suffix.lower() == ".pcap"):
                raise ScanError(
                    f"{path}: its frames carry no time, which --poses-track needs (bags and pcap "
                    "captures do); give one pose per frame with --poses"
                )
            track = timed
        elif args.poses_topic:
            track = bag_pose_track(path, args.poses_topic, stamps=args.stamps, max_gap_s=args.max_pose_gap)
        elif args.tf:
            tree = bag_transform_tree(path, stamps=args.stamps)
            track = tree.chain(*args.tf, max_gap_s=args.max_pose_gap, body_height_m=args.body_height)
        if args.cloud:
            stream = bag_clouds(path, setups, stamps=args.stamps, point_times=args.deskew)
        else:
            frames = read_recording(
                path,
                setups[lead],
                bin_layout=args.bin_fields,
                topic=args.topic,
                stamps=args.stamps,
                point_times=args.deskew,
            )
            stream = ((lead, frame) for frame in frames)
        mounted = _mounted(stream, tree, setups, args)
        for update in synchronise(mounted, lead, others, window_s=window_s):
            yield update, track


def _mounted(
    stream: Iterator[tuple[str, RecordedFrame]],
    tree: TransformTree | None,
    setups: dict[str, ScanSetup],
    args: argparse.Namespace,
) -> Iterator[tuple[str, RecordedFrame]]:
    """``stream`` with each topic's mounting checked against the tf tree at its first cloud and,
    with ``--mount-from-tf``, taken from it."""
    mountings: dict[str, tuple[np.ndarray, np.ndarray] | None] = {}
    for topic, frame in stream:
        if topic not in mountings:
            mountings[topic] = None
            if tree is not None and args.mount_from_tf:
                mountings[topic] = _tf_mounting(tree, args, frame)
            if tree is not None and frame.frame_id:
                _check_mounting(tree, args.tf[1], frame, setups[topic], args)
        mounting = mountings[topic]
        if mounting is not None:
            scan = dataclasses.replace(frame.scan, rotation=mounting[0], translation_m=mounting[1])
            frame = dataclasses.replace(frame, scan=scan)
        yield topic, frame


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
    """``--mount-from-tf`` and ``--body-height`` need ``--tf``; ``--height`` is the tree's then;
    ``--deskew`` needs timed poses."""
    from negobs_gym.errors import ScanError

    if args.tf is None and (args.mount_from_tf or args.body_height):
        raise ScanError("--mount-from-tf and --body-height go with --tf FIXED:BODY")
    if args.deskew and not (args.poses_track or args.poses_topic or args.tf):
        raise ScanError("--deskew needs the vehicle's motion in time: --poses-track, --poses-topic or --tf")
    if args.mount_from_tf and (args.height is not None or any(c.height_m for c in args.cloud or ())):
        raise ScanError(
            "--height and --mount-from-tf both set the sensor's height (so does --cloud's HEIGHT): give one"
        )
    if args.mount is not None and (args.height is not None or args.mount_from_tf or args.cloud):
        raise ScanError(
            "--mount sets the whole mounting of a single sensor: drop --height, --mount-from-tf and --cloud"
        )


def scan_setup(args: argparse.Namespace) -> ScanSetup:
    """The :class:`ScanSetup` for ``--sensor``, ``--height`` or ``--mount``, and
    ``--azimuth-resolution``."""
    setup = _setup(args.sensor or DEFAULT_SENSOR, args.height, args.azimuth_resolution)
    if args.mount is None:
        return setup
    from scipy.spatial.transform import Rotation

    from negobs_gym.detector.io.setup import mounting_from_ros

    x, y, z, roll, pitch, yaw = args.mount
    turn = Rotation.from_euler("xyz", [roll, pitch, yaw], degrees=True).as_matrix()
    rotation, translation = mounting_from_ros(np.array([x, y, z]), turn)
    # the detector's path is the sensor's spin axis: upright (§3.1) or rolled 90 deg (§3.2)
    spin, expected = rotation[:, 2], np.asarray(setup.rotation)[:, 2]
    off = float(np.degrees(np.arccos(np.clip(spin @ expected, -1.0, 1.0))))
    if off > PATH_TOLERANCE_DEG:
        log.warning(
            "--mount tilts the sensor's spin axis %.1f deg from the --sensor %s mounting's, whose "
            "detector path (upright or rolled) reads it; pick the --sensor mounted nearest",
            off,
            args.sensor or DEFAULT_SENSOR,
        )
    return dataclasses.replace(
        setup,
        rotation=tuple(tuple(float(v) for v in row) for row in rotation),
        translation_m=tuple(float(v) for v in translation),
    )


def _setup(sensor: str, height_m: float | None, azimuth_resolution_deg: float | None) -> ScanSetup:
    """A recorded sensor's setup: its paper N or paper T rig mount, at ``height_m`` when given."""
    from negobs_gym.detector.io import ScanSetup
    from negobs_gym.sensors.rigs import paper_n_rig, paper_t_rig

    spec = recorded_sensors()[sensor]
    mount = next(m for m in paper_n_rig().mounts + paper_t_rig().mounts if m.name == spec.mount)
    x, y, z = mount.translation_m
    return ScanSetup(
        sensor=mount.name,
        azimuth_resolution_deg=azimuth_resolution_deg or spec.azimuth_resolution_deg,
        elevation_rad=tuple(math.radians(v) for v in spec.elevation_deg),
        rotation=tuple(tuple(float(v) for v in row) for row in mount.rotation_matrix),
        translation_m=(x, y, z if height_m is None else height_m),
        columns_centred=spec.columns_centred,
        crop_columns=spec.crop_columns,
    )


def scan_setups(args: argparse.Namespace) -> dict[str, ScanSetup]:
    """The setup of each ``--cloud`` topic, the lead's first; without ``--cloud`` the one of
    :func:`scan_setup` (keyed by the sensor's name).

    Raises:
        ScanError: ``--cloud`` with ``--topic``, ``--sensor``, ``--height`` or
            ``--azimuth-resolution``, or with files that are not bags; a topic named twice; two
            clouds feeding the same detector input (two upright sensors, or two on one side).
    """
    from negobs_gym.detector.io.recording import is_bag
    from negobs_gym.errors import ScanError

    if not args.cloud:
        if args.sync_window is not None:
            raise ScanError("--sync-window goes with --cloud (several topics of one bag)")
        return {args.sensor or DEFAULT_SENSOR: scan_setup(args)}
    single = {
        "--topic": args.topic,
        "--sensor": args.sensor,
        "--height": args.height,
        "--azimuth-resolution": args.azimuth_resolution,
    }
    given = [flag for flag, value in single.items() if value is not None]
    if given:
        raise ScanError(f"--cloud names each topic's sensor and height: drop {', '.join(given)}")
    not_bags = [path for path in args.files if not is_bag(path)]
    if not_bags:
        raise ScanError(f"--cloud reads several topics of a bag; not bags: {not_bags}")
    setups: dict[str, ScanSetup] = {}
    for cloud in args.cloud:
        if cloud.topic in setups:
            raise ScanError(f"--cloud names {cloud.topic} twice")
        setup = _setup(cloud.sensor, cloud.height_m, None)
        taken = [topic for topic, other in setups.items() if other.sensor == setup.sensor]
        if taken:
            raise ScanError(
                f"--cloud {cloud.topic}:{cloud.sensor} and {taken[0]} both feed the detector's "
                f"{setup.sensor} input; paper N's rig has one upright sensor and one rolled on each side, "
                "paper T's one 4-layer LiDAR"
            )
        setups[cloud.topic] = setup
    return setups


def _scans_at_lead_time(
    update: SynchronisedFrames, track: PoseTrack | TransformChain | None
) -> tuple[dict[str, StructuredScan], dict[str, np.ndarray | None]]:
    """The update's scans by detector input, and by topic the vehicle's motion ``[M | m]`` from
    each cloud's time to the lead's (None without timed poses). With timed poses each other
    topic's cloud is brought to the lead's time (:func:`~negobs_gym.detector.io.sync.scan_at_time`),
    else taken as at it; a cloud read with its columns' times (``--deskew``) is deskewed to it, the
    lead's included."""
    from negobs_gym.detector.io.sync import scan_at_time, vehicle_motion
    from negobs_gym.errors import ScanError

    scans, motions = {}, {}
    for topic, frame in update.clouds.items():
        scan = frame.scan
        motions[topic] = None
        if track is not None:
            where = f"{frame.source}, {frame.scan.sensor} cloud {frame.index}"
            try:
                motions[topic] = vehicle_motion(track, scan.timestamp_s, update.time_s)
                if frame is not update.lead or frame.column_time_s is not None:
                    scan = scan_at_time(scan, track, update.time_s, column_time_s=frame.column_time_s)
            except ScanError as error:  # name the cloud: one outside the odometry's span
                raise ScanError(f"{where}: {error}") from error
        scans[frame.scan.sensor] = scan
    return scans, motions


def run(args: argparse.Namespace) -> int:
    """Detect on every frame of ``args.files``; writes the per-frame files and ``summary.json``."""
    from tqdm import tqdm

    from negobs_gym.cli.detect_report import cloud_records, detection_record, plot_detection
    from negobs_gym.core.pose import Pose
    from negobs_gym.detector import NegativeObstacleDetector, StructureDetector, TraversableRegionDetector
    from negobs_gym.detector.io import read_poses_csv
    from negobs_gym.errors import ScanError

    _check_tf_options(args)
    setups = scan_setups(args)
    setup = next(iter(setups.values()))  # the lead's
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
    if poses is not None and len(setups) > 1:
        log.warning(
            "%s gives a pose per update, untimed: the other --cloud topics' clouds are taken as at "
            "the lead's time, up to --sync-window apart (--poses-track, --poses-topic or --tf bring "
            "them to it)",
            poses_file,
        )
    configs = detector_configs(args.settings, tighten_pairs=args.tighten_pairs)
    detector = NegativeObstacleDetector(configs["negative"])
    structure = StructureDetector(configs["structure"], grid=detector.config.grid)
    traversable = TraversableRegionDetector(configs["traversable"], grid=detector.config.grid)
    recall = _recorded_recall(args, setups, detector.config.grid)
    record_settings = {name: dataclasses.asdict(config) for name, config in configs.items()}
    record_settings["set"] = args.settings
    write_atomic(out / "config.json", lambda tmp: tmp.write_text(json.dumps(record_settings, indent=1)))
    summary = []
    missing = dict.fromkeys(setups, 0)  # --cloud: updates each topic had no cloud in

    updates = _updates(args, setups)
    bar = tqdm(updates, desc="negobs detect", unit="frame", disable=None)
    for n, (update, track) in enumerate(bar):
        frame = update.lead
        if poses is not None and n >= len(poses):
            raise ScanError(f"{poses_file}: {len(poses)} poses, but the recording has more frames")
        if track is not None:
            try:
                pose = track.at(frame.scan.timestamp_s)
            except ScanError as error:  # name the frame: a cloud outside the odometry's span
                raise ScanError(f"{frame.source}, frame {frame.index}: {error}") from error
        else:
            pose = poses[n] if poses is not None else Pose()
        scans, motions = _scans_at_lead_time(update, track)
        detection = cells = region = None
        if set(scans) - {LUX_MOUNT}:  # paper N's inputs
            detection = detector.update(scans, pose)
            cells = structure.update(scans, pose, detection.ground_map)
        if LUX_MOUNT in scans:
            try:
                region = traversable.update(scans[LUX_MOUNT], pose)
            except ScanError as error:  # e.g. a layer field with fewer than the LUX's 4 layers
                lux = next(f for f in update.clouds.values() if f.scan.sensor == LUX_MOUNT)
                raise ScanError(f"{lux.source}, LUX cloud {lux.index}: {error}") from error
        stem = f"{n:05d}_{Path(frame.source).stem}_{frame.index:04d}"  # n: the same file may repeat
        given = poses is not None or track is not None
        sensor = args.cloud[0].sensor if args.cloud else args.sensor or DEFAULT_SENSOR
        found = {"detection": detection, "structure": cells, "region": region, "grid": detector.config.grid}
        record = detection_record(frame, sensor, pose if given else None, **found)
        record["deskewed"] = args.deskew
        if recall is not None and detection is not None:
            outlines = [ob.outline_xy_m for ob in detection.obstacles]
            record["truth"] = recall.add(outlines, pose if given else None)
        if args.cloud:
            record["clouds"] = cloud_records(update, {c.topic: c.sensor for c in args.cloud}, motions)
        write_atomic(out / f"{stem}.json", lambda tmp, r=record: tmp.write_text(json.dumps(r, indent=1)))
        if not args.no_png and n % args.png_every == 0:
            write_atomic(
                out / f"{stem}.png",
                lambda tmp, f=frame, s=scans, found=found: plot_detection(f, tmp, s.values(), **found),
            )
        line = _summary(record)
        summary.append({"frame": stem, **line, **({"n_clouds": len(update.clouds)} if args.cloud else {})})
        log.debug("%s: %s", stem, line)
        for topic in setups:
            missing[topic] += topic not in update.clouds
    write_atomic(out / "summary.json", lambda tmp: tmp.write_text(json.dumps(summary, indent=1)))
    if recall is not None:
        totals = recall.summary()
        write_atomic(out / "recall.json", lambda tmp: tmp.write_text(json.dumps(totals, indent=1)))
        write_atomic(out / "recall.md", lambda tmp: tmp.write_text(recall.markdown()))
        log.info("--truth: recall by distance %s (%s)", totals["recall_by_distance"], out / "recall.md")
    if args.cloud and any(missing.values()):
        log.warning(
            "--cloud: no cloud within --sync-window of the lead's for %s",
            ", ".join(f"{topic} in {n} of {len(summary)} updates" for topic, n in missing.items() if n),
        )
    if poses is not None and len(poses) > len(summary):
        log.warning(
            "%s: %d poses for %d frames; the last %d unused",
            poses_file,
            len(poses),
            len(summary),
            len(poses) - len(summary),
        )
    log.info(
        "negobs detect: %d frames, the last %s, written to %s",
        len(summary),
        summary[-1] if summary else {},
        out,
    )
    return 0


def detector_configs(settings: list[str], *, tighten_pairs: bool = False) -> dict[str, Any]:
    """The configs of the three detectors, by ``--set`` section (``negative``, ``traversable``,
    ``structure``), with ``--tighten-pairs`` and then each ``--set`` applied.

    Raises:
        ConfigError: an assignment outside the three sections, or one the section refuses
            (:func:`~negobs_gym.core.settings.replace_setting`).
    """
    from negobs_gym.core.settings import OPTION, parse_assignment, replace_setting
    from negobs_gym.detector import FusionConfig, NegativeDetectorConfig, StructureConfig, TraversableConfig
    from negobs_gym.errors import ConfigError

    configs: dict[str, Any] = {
        "negative": NegativeDetectorConfig(fusion=FusionConfig(tighten_on_match=tighten_pairs)),
        "traversable": TraversableConfig(),
        "structure": StructureConfig(),
    }
    for text in settings:
        keys, value = parse_assignment(text, example="negative.fusion.prior=0.4")
        if keys[0] not in configs or len(keys) < 2:
            raise ConfigError(OPTION, f"{text!r}: starts with the detector, one of {', '.join(configs)}")
        configs[keys[0]] = replace_setting(configs[keys[0]], keys[1:], value, f"{keys[0]}.")
    return configs


def _recorded_recall(
    args: argparse.Namespace, setups: dict[str, ScanSetup], grid: GridSpec
) -> RecordedRecall | None:
    """``--truth``: the surveyed obstacles' recall counter, or None without it.

    Raises:
        ScanError: ``--truth`` without a paper N input (only a 4-layer LiDAR).
    """
    from negobs_gym.errors import ScanError
    from negobs_gym.eval.recorded import RecordedRecall, read_surveyed_obstacles

    if args.truth is None:
        return None
    if all(setup.sensor == LUX_MOUNT for setup in setups.values()):
        raise ScanError("--truth judges paper N's negative obstacles; a 4-layer LiDAR alone gives none")
    return RecordedRecall(read_surveyed_obstacles(args.truth), grid=grid)


def _summary(record: dict) -> dict:
    """A frame's line of ``summary.json``: its points and what each detector that ran found."""
    line = {"n_points": record["n_points"]}
    if "n_frame_pairs" in record:
        line.update(
            n_frame_pairs=record["n_frame_pairs"],
            n_obstacles=record["n_obstacles"],
            n_structure_cells=len(record["structure_cells"]),
        )
    if "truth" in record:
        judged = record["truth"]["obstacles"]
        line.update(
            truth_in_grid=len(judged),
            truth_recalled=sum(o["recalled"] for o in judged),
            false_alarms=record["truth"]["false_alarms"],
        )
    if "traversable" in record:
        region = record["traversable"]
        line.update(
            n_traversable_cells=len(region["traversable_cells"]),
            n_positive_obstacles=region["n_obstacles"],
            boundaries=[side for side in ("left", "right") if region[f"{side}_line"] is not None],
        )
    return line
