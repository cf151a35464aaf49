"""Raw Velodyne packet captures (``velodyne-decoder``, extra ``negobs_gym[real]``).

The decoder recognises the model from the packets (HDL-32E, VLP-16, VLP-32C, HDL-64E, VLS-128
with their bundled calibrations) and cuts the stream into revolutions; every point carries its
ring, so row elevations are measured from the points. A capture is a sequence of frames; the last
one may be a partial revolution (as recorded).
"""

from __future__ import annotations

import logging
import os
import struct
from collections.abc import Iterator

import numpy as np

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io._optional import optional_import
from negobs_gym.detector.io.frame import RecordedFrame, check_not_empty, unreadable
from negobs_gym.detector.io.setup import ScanSetup, column_time_offsets, fields_to_scan
from negobs_gym.errors import ScanError

log = logging.getLogger(__name__)


def truncated_at(path: str) -> int | None:
    """Byte offset of a last packet record cut short (a capture stopped mid-write), else None.

    Walks the libpcap record headers only (16 bytes each, one seek per packet, no payload read).
    """
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        magic = f.read(4)
        order = {
            b"\xd4\xc3\xb2\xa1": "<",
            b"\x4d\x3c\xb2\xa1": "<",
            b"\xa1\xb2\xc3\xd4": ">",
            b"\xa1\xb2\x3c\x4d": ">",
        }
        if magic not in order:
            return None  # not classic libpcap (pcapng or junk): the decoder reports it
        offset = 24
        while offset + 16 <= size:
            f.seek(offset + 8)
            (incl_len,) = struct.unpack(order[magic] + "I", f.read(4))
            if offset + 16 + incl_len > size:
                return offset
            offset += 16 + incl_len
        return offset if offset < size else None


def pcap_frames(
    path: str | os.PathLike[str], setup: ScanSetup, *, point_times: bool = False
) -> Iterator[RecordedFrame]:
    """One frame per revolution of a Velodyne pcap (sensor frame x forward, y left, z up), timed by
    the capture's host clock; with ``point_times`` each frame's ``column_time_s`` from the decoder's
    per-point times (after that stamp)."""
    vd = optional_import("velodyne_decoder", "velodyne-decoder", "reading Velodyne pcap files")
    name = os.fspath(path)
    check_not_empty(name)
    cut = truncated_at(name)
    if cut is not None:
        log.warning("%s: capture ends inside a packet at byte %d; reading the packets before it", name, cut)
    index = 0
    try:
        for stamp, points in vd.read_pcap(name, vd.Config(), as_pcl_structs=True):
            fields = {k: np.asarray(points[k]) for k in ("x", "y", "z", "intensity", "ring", "time")}
            source = f"{name}#{index}"
            scan, ring_source = fields_to_scan(fields, setup, source=source, timestamp_s=stamp.host)
            columns = (
                column_time_offsets(fields, setup, source=source, stamp_s=stamp.host) if point_times else None
            )
            yield RecordedFrame(scan, name, index, ring_source, int(points.shape[0]), column_time_s=columns)
            index += 1
    except ScanError:
        raise
    except Exception as error:  # the decoder raises ValueError/RuntimeError/dpkt errors on bad captures
        raise unreadable(name, "Velodyne pcap", error) from error
    if index == 0:
        raise ScanError(f"{name}: no Velodyne data packets in the capture")


def read_pcap(path: str | os.PathLike[str], setup: ScanSetup | None = None) -> Iterator[StructuredScan]:
    """The structured scans of a Velodyne pcap, one per revolution (see :func:`pcap_frames`)."""
    return (frame.scan for frame in pcap_frames(path, setup or ScanSetup()))
