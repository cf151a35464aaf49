"""Detectors that turn structured LiDAR scans into vehicle-centred obstacle grids.

numpy / scipy / scikit-learn only: nothing here imports a simulator or gymnasium, so the detectors
run on recorded scans from a real vehicle (see :mod:`negobs_gym.detector.loaders`).

- Paper N, negative obstacles: per-sensor feature point pairs (:mod:`~negobs_gym.detector.hdl64`,
  :mod:`~negobs_gym.detector.hdl32`, Eq. 11–14 in :mod:`~negobs_gym.detector.pair_test`) and the
  geometry of paper N §2 (:mod:`~negobs_gym.detector.geometry`), Bayesian fusion
  (:mod:`~negobs_gym.detector.fusion`), the ROI step of Table 1 (:mod:`~negobs_gym.detector.roi`),
  DBSCAN (:mod:`~negobs_gym.detector.clustering`), the grid (:mod:`~negobs_gym.detector.grid`), all
  behind :class:`NegativeObstacleDetector`.
- Paper T, traversable region from a 4-layer LiDAR: :mod:`negobs_gym.detector.traversable`.
- Positive obstacles from paper N's rig (in neither paper): returns standing above the ROI ground
  map, :class:`StructureDetector` (:mod:`~negobs_gym.detector.structure`).
"""

from negobs_gym.detector.clustering import ClusteringConfig, DetectedObstacle, cluster_obstacles
from negobs_gym.detector.config import Hdl32FeatureConfig, Hdl64FeatureConfig, PairTestConfig
from negobs_gym.detector.fusion import FusedPairs, FusionConfig, PairFusion, SensorLikelihood
from negobs_gym.detector.grid import convex_overlap_mask, obstacle_grid
from negobs_gym.detector.hdl32 import extract_hdl32_pairs
from negobs_gym.detector.hdl64 import extract_hdl64_pairs
from negobs_gym.detector.negative import (
    SENSOR_MODES,
    Detection,
    NegativeDetectorConfig,
    NegativeObstacleDetector,
)
from negobs_gym.detector.pairs import FeaturePairs
from negobs_gym.detector.roi import GroundMap, RoiConfig, build_ground_map
from negobs_gym.detector.structure import StructureConfig, StructureDetector, structure_points
from negobs_gym.detector.traversable import (
    TraversableConfig,
    TraversableRegion,
    TraversableRegionDetector,
)

__all__ = [
    "SENSOR_MODES",
    "ClusteringConfig",
    "DetectedObstacle",
    "Detection",
    "FeaturePairs",
    "FusedPairs",
    "FusionConfig",
    "GroundMap",
    "Hdl32FeatureConfig",
    "Hdl64FeatureConfig",
    "NegativeDetectorConfig",
    "NegativeObstacleDetector",
    "PairFusion",
    "PairTestConfig",
    "RoiConfig",
    "SensorLikelihood",
    "StructureConfig",
    "StructureDetector",
    "TraversableConfig",
    "TraversableRegion",
    "TraversableRegionDetector",
    "build_ground_map",
    "cluster_obstacles",
    "convex_overlap_mask",
    "extract_hdl32_pairs",
    "extract_hdl64_pairs",
    "obstacle_grid",
    "structure_points",
]
