"""The sensors and scan setups of ``negobs detect``: what ``--sensor`` and ``--cloud`` can name
(:func:`recorded_sensors`), and the :class:`~negobs_gym.detector.io.ScanSetup` each cloud is read
with (``--sensor``, ``--height``, ``--mount``, ``--azimuth-resolution``, ``--cloud``)."""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from negobs_gym.cli.common import positive_float

if TYPE_CHECKING:
    from negobs_gym.detector.io import ScanSetup

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
