"""Shared data types and frames: poses, structured LiDAR scans, vehicle-centred grids.

numpy only: the detectors, the sensors and the simulator all speak these types, so this
subpackage imports none of them. :mod:`negobs_gym.core.files` writes every result file atomically.
"""

from negobs_gym.core.grid import GridSpec
from negobs_gym.core.pose import Pose, rotation_from_rpy
from negobs_gym.core.scan import StructuredScan

__all__ = ["GridSpec", "Pose", "StructuredScan", "rotation_from_rpy"]
