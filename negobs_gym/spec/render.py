"""Layout of an episode's top-down frames (``[render]`` of a scenario spec; display settings)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from negobs_gym.errors import require

__all__ = ["RenderConfig"]


@dataclass(frozen=True, kw_only=True)
class RenderConfig:
    """Layout and content of :func:`render_frame` (display settings, not paper values).

    Attributes:
        height_px: Frame height; even, so that video encoders (yuv420p) accept it.
        overview_width_px: Width of the whole-terrain panel.
        max_points: LiDAR returns drawn per frame (an evenly strided subset when there are more).
        point_z_range_m: Vehicle-frame heights mapped to the ends of the colour ramp [m]; the
            vehicle frame's origin is on the ground, so pit floors are blue and obstacles orange.
        border_px: Width of the safety-state border around the local panel.
        mark_thickness_px: Thickness of the hazard / braking distance marks.
        caption: Write the caption lines the caller gives (the envs: time, speed, applied action,
            d and R(v)) at the top left of the overview.
    """

    height_px: int = 480
    overview_width_px: int = 160
    max_points: int = 4000
    point_z_range_m: tuple[float, float] = (-1.0, 1.0)
    border_px: int = 5
    mark_thickness_px: int = 3
    caption: bool = True

    def __post_init__(self) -> None:
        require(
            isinstance(self.height_px, int) and self.height_px >= 32 and self.height_px % 2 == 0,
            "height_px",
            f"must be an even int >= 32, got {self.height_px!r}",
        )
        require(
            isinstance(self.overview_width_px, int)
            and self.overview_width_px >= 16
            and self.overview_width_px % 2 == 0,
            "overview_width_px",
            f"must be an even int >= 16, got {self.overview_width_px!r}",
        )
        require(
            isinstance(self.max_points, int) and self.max_points >= 0,
            "max_points",
            f"must be an int >= 0, got {self.max_points!r}",
        )
        lo, hi = self.point_z_range_m
        require(
            math.isfinite(lo) and math.isfinite(hi) and lo < hi,
            "point_z_range_m",
            f"must be finite (low, high) with low < high, got {self.point_z_range_m!r}",
        )
        require(isinstance(self.caption, bool), "caption", f"must be a bool, got {self.caption!r}")
        for name in ("border_px", "mark_thickness_px"):
            v = getattr(self, name)
            require(isinstance(v, int) and 1 <= v <= 20, name, f"must be an int in [1, 20], got {v!r}")
