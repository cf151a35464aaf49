"""Paper T: traversable-region detection with a 4-layer LiDAR (IBEO LUX).

numpy/scipy only; no simulator imports. Entry point: :class:`TraversableRegionDetector`.
"""

from negobs_gym.detector.traversable.boundaries import BoundaryLine, fit_boundary
from negobs_gym.detector.traversable.config import TraversableConfig
from negobs_gym.detector.traversable.detector import TraversableRegion, TraversableRegionDetector
from negobs_gym.detector.traversable.obstacles import ObstacleCluster
from negobs_gym.detector.traversable.synthetic import (
    Box,
    Bump,
    LuxRig,
    TrackScene,
    random_bumps,
    synthetic_scan,
)

__all__ = [
    "BoundaryLine",
    "Box",
    "Bump",
    "LuxRig",
    "ObstacleCluster",
    "TrackScene",
    "TraversableConfig",
    "TraversableRegion",
    "TraversableRegionDetector",
    "fit_boundary",
    "random_bumps",
    "synthetic_scan",
]
