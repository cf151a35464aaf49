"""Detection quality: paper N's recall per 2 m distance bin (Fig. 16) and its false alarms.

The figures come from the detection campaign of ``negobs eval detection``
(:func:`negobs_gym.eval.detection_campaign.run_detection_campaign`, paper N §4.2): straight rough
courses with paper N's pit mix beside the wheel tracks and verge clutter, driven at 10-25 km/h,
the native rig cast every 10 Hz frame with sensor noise. Recall is paper N Fig. 16's: of the
25-34-cell pits per 2 m distance bin, for the fused detector and each sensor alone. A recall may
be 0 (nothing recalled in that bin) and so may the false alarms.
"""

from __future__ import annotations

import itertools
import tempfile
from dataclasses import dataclass

from negobs_gym.bench.harness import BenchError, Figure, Figures, Suite, positive_counts
from negobs_gym.eval.campaign import Backend, RunOptions
from negobs_gym.eval.detection_campaign import DetectionCampaignConfig, run_detection_campaign

WORKERS = 2  # campaign worker processes: the machine's 2 cores
MODES = {"fused": "fused", "hdl64": "HDL-64 alone", "hdl32": "the side HDL-32s alone"}  # paper N Fig. 16


@dataclass(frozen=True)
class DetectionSize:
    """How much the detection campaign drives."""

    seeds: int  # courses
    frames: int  # frames over all courses

    def __post_init__(self) -> None:
        positive_counts(self)


def campaign(size: DetectionSize) -> Figures:
    """Recall of 25-34-cell pits per distance bin and sensor mode (paper N Fig. 16), and the fused
    false alarms, of one campaign."""
    config = DetectionCampaignConfig(seeds=size.seeds, frames=size.frames)
    options = RunOptions(backend=Backend(workers=min(WORKERS, size.seeds)), progress=False)
    with tempfile.TemporaryDirectory() as out:
        summary = run_detection_campaign(config, out, options).summary
    figures = {}
    bins = list(itertools.pairwise(config.matching.distance_bin_edges_m))
    for mode, who in MODES.items():
        for (lo, hi), recall in zip(bins, summary.fig16[mode], strict=True):
            key = f"{mode}_recall_{lo:g}_{hi:g}m"
            if recall is None:
                raise BenchError(f"{key}: no 25-34-cell pit seen at {lo:g}-{hi:g} m; drive more frames")
            figures[key] = Figure(recall, "", f"recall of 25-34-cell pits at {lo:g}-{hi:g} m, {who}")
    rates = summary.false_alarm_rates("fused")
    runs = f"{summary.frames} frames, {summary.km:.2f} km"
    figures["false_alarms_per_frame"] = Figure(
        rates["per_frame"], "", f"fused false alarms per frame ({runs})"
    )
    for part, where in (("total", "in all"), ("on_track", "on the track"), ("off_track", "off the track")):
        key = "false_alarms_per_km" + ("" if part == "total" else f"_{part}")
        figures[key] = Figure(rates[f"{part}_per_km"], "/km", f"fused false alarms per km {where}")
    return figures


SUITE = Suite(
    name="detection",
    what="detection quality",
    full=DetectionSize(seeds=10, frames=1000),
    quick=DetectionSize(seeds=2, frames=120),
    measurements=(campaign,),
)
