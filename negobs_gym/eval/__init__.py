"""Evaluation helpers (docs/eval.md): detection recall and false alarms on the vehicle grid."""

from negobs_gym.eval.detection import (
    DetectionEvalConfig,
    FrameMatch,
    RecallTable,
    components_from_grid,
    match_frame,
    rasterize_outline,
    track_border_mask,
    world_outline_to_vehicle,
)

__all__ = [
    "DetectionEvalConfig",
    "FrameMatch",
    "RecallTable",
    "components_from_grid",
    "match_frame",
    "rasterize_outline",
    "track_border_mask",
    "world_outline_to_vehicle",
]
