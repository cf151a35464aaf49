"""PCD files (``pypcd4``, extra ``negobs_gym[real]``): ASCII, binary and binary_compressed."""

from __future__ import annotations

import os

import numpy as np

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.io._optional import optional_import
from negobs_gym.detector.io.frame import RecordedFrame, check_not_empty, unreadable
from negobs_gym.detector.io.setup import ScanSetup, fields_to_scan


def read_pcd(path: str | os.PathLike[str], setup: ScanSetup) -> RecordedFrame:
    """One frame from a PCD file in the ROS frame (x forward, y left, z up); the ring comes from a
    ``ring``/``channel``/``laser_id`` field when there is one (see :func:`fields_to_scan`)."""
    pypcd4 = optional_import("pypcd4", "pypcd4", "reading PCD files")
    name = os.fspath(path)
    check_not_empty(name)
    try:
        cloud = pypcd4.PointCloud.from_path(name)
        data = cloud.pc_data
    except Exception as error:  # pypcd4 raises bare ValueError/KeyError/struct.error on bad files
        raise unreadable(name, "PCD file", error) from error
    fields = {k: np.asarray(data[k]) for k in data.dtype.names or ()}
    scan, ring_source = fields_to_scan(fields, setup, source=name)
    return RecordedFrame(scan, name, 0, ring_source, int(data.shape[0]))


def load_pcd(path: str | os.PathLike[str], setup: ScanSetup | None = None) -> StructuredScan:
    """The structured scan of a PCD file (see :func:`read_pcd`)."""
    return read_pcd(path, setup or ScanSetup()).scan
