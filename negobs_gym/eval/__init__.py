"""Evaluation: detection recall and false alarms on the vehicle grid (paper N §4.2) and campaigns.

The one episode loop (:mod:`~negobs_gym.eval.episode`), the scenario runner and the campaign
modules (:mod:`~negobs_gym.eval.campaign` runner, ``detection_campaign``, ``braking_campaign``,
``policy_campaign``, ``tables``, ``plots``) import the simulator and are not imported here, so
``negobs_gym.eval`` itself stays simulator-free.
"""

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
