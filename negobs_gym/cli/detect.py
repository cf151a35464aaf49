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

This module is the command (its options and its run); the sensors and scan setups are
:mod:`negobs_gym.cli.detect_sensors`'s, the input stream :mod:`negobs_gym.cli.detect_inputs`'s and
what is written per frame :mod:`negobs_gym.cli.detect_report`'s.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from negobs_gym.cli.common import non_negative_float, positive_float, positive_int
from negobs_gym.cli.detect_inputs import check_tf_options, detector_updates, scans_at_lead_time, tf_frames
from negobs_gym.cli.detect_sensors import (
    DEFAULT_SENSOR,
    LUX_MOUNT,
    cloud_spec,
    recorded_sensors,
    ros_mount,
    scan_setups,
)
from negobs_gym.core.files import write_atomic

if TYPE_CHECKING:
    from negobs_gym.core.grid import GridSpec
    from negobs_gym.core.pose import Pose
    from negobs_gym.detector.io import ScanSetup
    from negobs_gym.eval.recorded import RecordedRecall

log = logging.getLogger(__name__)


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
        "(StructureConfig), rings.* (the ring recovery from the point order of clouds without a ring "
        "field, loaders.PointOrderConfig: rings.back_step_deg=20); VALUE is TOML. The grid "
        "(negative.grid) is every detector's. OUT/config.json records the settings that ran",
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


def run(args: argparse.Namespace) -> int:
    """Detect on every frame of ``args.files``; writes the per-frame files and ``summary.json``."""
    from tqdm import tqdm

    from negobs_gym.cli.detect_report import cloud_records, detection_record, plot_detection
    from negobs_gym.core.pose import Pose
    from negobs_gym.detector import NegativeObstacleDetector, StructureDetector, TraversableRegionDetector
    from negobs_gym.errors import ScanError

    check_tf_options(args)
    configs = detector_configs(args.settings, tighten_pairs=args.tighten_pairs)
    setups = {
        name: dataclasses.replace(setup, point_order=configs["rings"])
        for name, setup in scan_setups(args).items()
    }
    setup = next(iter(setups.values()))  # the lead's
    out = Path(args.out)
    poses = _frame_poses(args, setup)
    poses_file = args.poses or args.kitti_poses or args.kitti_oxts
    if poses is not None and len(setups) > 1:
        log.warning(
            "%s gives a pose per update, untimed: the other --cloud topics' clouds are taken as at "
            "the lead's time, up to --sync-window apart (--poses-track, --poses-topic or --tf bring "
            "them to it)",
            poses_file,
        )
    detector = NegativeObstacleDetector(configs["negative"])
    structure = StructureDetector(configs["structure"], grid=detector.config.grid)
    traversable = TraversableRegionDetector(configs["traversable"], grid=detector.config.grid)
    recall = _recorded_recall(args, setups, detector.config.grid)
    record_settings = {name: dataclasses.asdict(config) for name, config in configs.items()}
    record_settings["set"] = args.settings
    write_atomic(out / "config.json", lambda tmp: tmp.write_text(json.dumps(record_settings, indent=1)))
    summary = []
    missing = dict.fromkeys(setups, 0)  # --cloud: updates each topic had no cloud in

    updates = detector_updates(args, setups)
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
        scans, motions = scans_at_lead_time(update, track)
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


def _frame_poses(args: argparse.Namespace, setup: ScanSetup) -> list[Pose] | None:
    """The vehicle's pose at each frame of the sequence, in order, from ``--poses``, or from
    ``--kitti-poses`` or ``--kitti-oxts`` with ``--kitti-calib`` (less the lead's mounting in
    ``setup``); None without them.

    Raises:
        ScanError: ``--kitti-calib`` without ``--kitti-poses`` or ``--kitti-oxts``, or they without it.
    """
    from negobs_gym.detector.io import read_poses_csv
    from negobs_gym.errors import ScanError

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
    return poses


def detector_configs(settings: list[str], *, tighten_pairs: bool = False) -> dict[str, Any]:
    """The configs of the three detectors and of the ring recovery, by ``--set`` section
    (``negative``, ``traversable``, ``structure``, ``rings``: the point order's thresholds for clouds
    without a ring field), with ``--tighten-pairs`` and then each ``--set`` applied.

    Raises:
        ConfigError: an assignment outside the three sections, or one the section refuses
            (:func:`~negobs_gym.core.settings.replace_setting`).
    """
    from negobs_gym.core.settings import OPTION, parse_assignment, replace_setting
    from negobs_gym.detector import FusionConfig, NegativeDetectorConfig, StructureConfig, TraversableConfig
    from negobs_gym.detector.loaders import PointOrderConfig
    from negobs_gym.errors import ConfigError

    configs: dict[str, Any] = {
        "negative": NegativeDetectorConfig(fusion=FusionConfig(tighten_on_match=tighten_pairs)),
        "traversable": TraversableConfig(),
        "structure": StructureConfig(),
        "rings": PointOrderConfig(),
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
