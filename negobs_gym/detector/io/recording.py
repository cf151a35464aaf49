"""The dispatch from a recording (a file or a bag folder) to its reader."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import numpy as np

from negobs_gym.detector.io.bags import bag_frames
from negobs_gym.detector.io.frame import RecordedFrame
from negobs_gym.detector.io.pcap import pcap_frames
from negobs_gym.detector.io.pcd import read_pcd
from negobs_gym.detector.io.setup import ScanSetup, fields_to_scan
from negobs_gym.detector.loaders import read_float32_cloud
from negobs_gym.errors import ScanError

__all__ = ["BinLayout", "RecordedFrame", "is_bag", "read_bin", "read_recording"]

BinLayout = Literal["xyzi", "xyzir"]


def read_bin(path: str | os.PathLike[str], setup: ScanSetup, layout: BinLayout = "xyzi") -> RecordedFrame:
    """A headerless float32 binary: KITTI ``x, y, z, intensity`` or ``x, y, z, intensity, ring``."""
    names = {"xyzi": ("x", "y", "z", "intensity"), "xyzir": ("x", "y", "z", "intensity", "ring")}
    if layout not in names:
        raise ScanError(f"bin layout must be one of {sorted(names)}, got {layout!r}")
    cloud = read_float32_cloud(path, len(names[layout]))
    if not np.isfinite(cloud).all():
        raise ScanError(f"{os.fspath(path)}: cloud contains NaN or inf values")
    fields = dict(zip(names[layout], cloud.T, strict=True))
    scan, ring_source = fields_to_scan(fields, setup, source=os.fspath(path))
    return RecordedFrame(scan, os.fspath(path), 0, ring_source, cloud.shape[0])


def is_bag(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names a ROS bag: a ROS 1 ``.bag``, a ROS 2 ``.db3`` or ``.mcap``, or a ROS 2
    bag's folder (holding ``metadata.yaml``)."""
    p = Path(path)
    return p.suffix.lower() in (".bag", ".db3", ".mcap") or (p.is_dir() and (p / "metadata.yaml").exists())


def read_recording(
    path: str | os.PathLike[str],
    setup: ScanSetup,
    *,
    bin_layout: BinLayout = "xyzi",
    topic: str | None = None,
    stamps: str = "record",
    point_times: bool = False,
) -> Iterator[RecordedFrame]:
    """Frames of one recording, chosen by its name: ``.bin`` (float32, ``bin_layout``), ``.pcd``,
    ``.pcap`` (raw Velodyne packets), ``.bag`` (ROS 1) or a ROS 2 bag (its folder, ``.db3`` or
    ``.mcap``; ``topic``, ``stamps`` and ``point_times`` as
    :func:`~negobs_gym.detector.io.bags.bag_frames`; ``point_times`` for bags and pcap only). PCD,
    bags and pcap need the ``negobs_gym[real]`` extra."""
    p = Path(path)
    if not p.exists():
        raise ScanError(f"{p}: no such file or folder")
    suffix = p.suffix.lower()
    if point_times and not (is_bag(p) or suffix == ".pcap"):
        raise ScanError(f"{p}: per-point times are read from bags and pcap captures only")
    if suffix == ".bin":
        yield read_bin(p, setup, bin_layout)
    elif suffix == ".pcd":
        yield read_pcd(p, setup)
    elif suffix == ".pcap":
        yield from pcap_frames(p, setup, point_times=point_times)
    elif is_bag(p):
        yield from bag_frames(p, setup, topic=topic, stamps=stamps, point_times=point_times)
    else:
        raise ScanError(f"{p}: unknown recording type (expected .bin, .pcd, .pcap, .bag, a ROS 2 bag)")
