"""Raw Velodyne packet captures (``velodyne-decoder``, extra ``negobs_gym[real]``).

The decoder recognises the model from the packets (HDL-32E, VLP-16, VLP-32C, HDL-64E, VLS-128
with their bundled calibrations) and cuts the stream into revolutions; every point carries its
ring, so row elevations are measured from the points. A capture is a sequence of frames; the last
one may be a partial revolution (as recorded).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io._optional import optional_import
from negobs_gym.detector.io.recording import RecordedFrame
from negobs_gym.detector.io.setup import ScanSetup, fields_to_scan
from negobs_gym.errors import ScanError


def pcap_frames(path: str | os.PathLike[str], setup: ScanSetup) -> Iterator[RecordedFrame]:
    """One frame per revolution of a Velodyne pcap (sensor frame x forward, y left, z up)."""
    vd = optional_import("velodyne_decoder", "velodyne-decoder", "reading Velodyne pcap files")
    name = os.fspath(path)
    if os.path.getsize(name) == 0:
        raise ScanError(f"{name}: file is empty")
    index = 0
    try:
        for stamp, points in vd.read_pcap(name, vd.Config(), as_pcl_structs=True):
            fields = {k: np.asarray(points[k]) for k in ("x", "y", "z", "intensity", "ring")}
            scan, ring_source = fields_to_scan(
                fields, setup, source=f"{name}#{index}", timestamp_s=stamp.host
            )
            yield RecordedFrame(scan, name, index, ring_source, int(points.shape[0]))
            index += 1
    except ScanError:
        raise
    except Exception as error:  # the decoder raises ValueError/RuntimeError/dpkt errors on bad captures
        raise ScanError(f"{name}: not a readable Velodyne pcap ({type(error).__name__}: {error})") from error
    if index == 0:
        raise ScanError(f"{name}: no Velodyne data packets in the capture")


def read_pcap(path: str | os.PathLike[str], setup: ScanSetup | None = None) -> Iterator[StructuredScan]:
    """The structured scans of a Velodyne pcap, one per revolution (see :func:`pcap_frames`)."""
    return (frame.scan for frame in pcap_frames(path, setup or ScanSetup()))
