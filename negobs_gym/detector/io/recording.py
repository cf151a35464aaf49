"""One recorded frame with where it came from, and the dispatch from a file to its reader."""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io.setup import ScanSetup, fields_to_scan
from negobs_gym.detector.loaders import RingSource, read_float32_cloud
from negobs_gym.errors import ScanError

BinLayout = Literal["xyzi", "xyzir"]


@dataclass(frozen=True, eq=False)
class RecordedFrame:
    """A structured scan read from a recording.

    Attributes:
        scan: The frame as the detector reads it.
        source: File (or bag / pcap) it came from.
        index: Frame number within ``source``, from 0.
        ring_source: How each point's laser was found: ``"ring_field"``, ``"point_order"`` or
            ``"elevation_table"`` (see :mod:`negobs_gym.detector.loaders`).
        n_points: Points in the recorded cloud (before binning).
        frame_id: The cloud's coordinate frame where the recording names it (a bag message's
            ``header.frame_id``), else None.
        column_time_s: When each column of ``scan`` was fired, after the cloud's stamp [s]
            (:func:`~negobs_gym.detector.io.setup.column_time_offsets`), where it was read; None
            otherwise.
    """

    scan: StructuredScan
    source: str
    index: int
    ring_source: RingSource
    n_points: int
    frame_id: str | None = None
    column_time_s: np.ndarray | None = None


def unreadable(name: str, what: str, error: BaseException) -> ScanError:
    """One-line :class:`ScanError` for a file a third-party reader rejected (its message's first line)."""
    first = (str(error).strip().splitlines() or [""])[0]
    return ScanError(f"{name}: not a readable {what} ({type(error).__name__}: {first})")


def check_not_empty(name: str) -> None:
    """ScanError if ``name`` is an empty file (third-party readers give obscure messages for it)."""
    if os.path.isfile(name) and os.path.getsize(name) == 0:
        raise ScanError(f"{name}: file is empty")


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
        from negobs_gym.detector.io.pcd import read_pcd

        yield read_pcd(p, setup)
    elif suffix == ".pcap":
        from negobs_gym.detector.io.pcap import pcap_frames

        yield from pcap_frames(p, setup, point_times=point_times)
    elif is_bag(p):
        from negobs_gym.detector.io.bags import bag_frames

        yield from bag_frames(p, setup, topic=topic, stamps=stamps, point_times=point_times)
    else:
        raise ScanError(f"{p}: unknown recording type (expected .bin, .pcd, .pcap, .bag, a ROS 2 bag)")
