"""The input stream of ``negobs detect``: its detector updates (each file's clouds, synchronised
across the ``--cloud`` topics, with the bag's pose track), the tf tree's mounting checked against the
``--sensor`` one or taken (``--mount-from-tf``), and each update's scans brought to its lead cloud's
time."""

from __future__ import annotations

import argparse
import dataclasses
import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from negobs_gym.cli.detect_sensors import MOUNT_TOLERANCE_DEG, PATH_TOLERANCE_DEG

if TYPE_CHECKING:
    from collections.abc import Iterator

    from negobs_gym.core.scan import StructuredScan
    from negobs_gym.detector.io import PoseTrack, RecordedFrame, ScanSetup
    from negobs_gym.detector.io.sync import SynchronisedFrames
    from negobs_gym.detector.io.tf import TransformChain, TransformTree

log = logging.getLogger(__name__)


def tf_frames(text: str) -> tuple[str, str]:
    """``FIXED:BODY`` as two frame names (argparse type of ``--tf``)."""
    parts = text.split(":")
    if len(parts) != 2 or not all(part.strip("/ ") for part in parts):
        raise argparse.ArgumentTypeError(
            f"want two frame names FIXED:BODY (e.g. odom:base_link), got {text!r}"
        )
    return parts[0].strip(), parts[1].strip()


def check_tf_options(args: argparse.Namespace) -> None:
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


def detector_updates(
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


def scans_at_lead_time(
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
