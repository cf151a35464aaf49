"""Causes of false alarms: the true terrain class under each detection that matched no ground truth.

Each false alarm (a detected obstacle overlapping no ground-truth obstacle and no track-border band,
:func:`negobs_gym.eval.detection.match_frame`) is labelled from the simulator's terrain record
(:class:`negobs_gym.sim.types.Terrain`: the track's centre line, width and border kinds, the
verge width, the positive obstacles and the heightfield), first match wins:

1. ``beside <kind>``: the outline comes within ``positive_margin_m`` of a positive obstacle's
   footprint (rock, mound, vehicle; other kinds are ``beside other``) — its foot or the shadow
   behind it;
2. ``track``: the outline's centre lies on the drivable track;
3. ``verge``: on the grass strip between the track edge and a bank, a drop-off or the rough ground;
4. ``bank`` / ``drop-off``: beyond the verge on a side with that border;
5. ``rough ground``: beyond the verge, and the true ground under the outline (plus ``relief_margin_m``)
   spans at least ``rough_relief_m`` of height (off-track bumps and hollows);
6. ``other``: anything else (smooth ground off the track, or off the heightfield).

Pure numpy/scipy on the terrain record; no simulator is built.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from negobs_gym.core.geometry import distance_to_polyline, points_in_polygon
from negobs_gym.errors import GeometryError, require
from negobs_gym.eval.plots import pyplot, save_png

CAUSES: tuple[str, ...] = (
    "track",
    "verge",
    "bank",
    "drop-off",
    "rough ground",
    "beside rock",
    "beside mound",
    "beside vehicle",
    "beside other",
    "other",
)
_BESIDE = {"rock": "beside rock", "mound": "beside mound", "vehicle": "beside vehicle"}
_BORDER = {"bank": "bank", "dropoff": "drop-off"}


@dataclass(frozen=True, kw_only=True)
class CauseConfig:
    """How near counts as "beside" and how much relief counts as rough (evaluation choices)."""

    # a rock or mound's foot and the shadow behind it: a 0.4 m rock seen from the 2 m high HDL-64
    # 4 m away shadows ~1 m of ground behind it
    positive_margin_m: float = 1.5
    # off-track bumps are 5-30 cm (docs/terrain.md); 15 cm of relief under a detection is a hollow
    # or a bump a LiDAR can see, less is smooth ground
    rough_relief_m: float = 0.15
    relief_margin_m: float = 0.3  # ground sampled this far around the outline's bounding box
    relief_step_m: float = 0.1  # sample spacing of that ground

    def __post_init__(self) -> None:
        for name in ("positive_margin_m", "rough_relief_m", "relief_margin_m"):
            v = getattr(self, name)
            require(math.isfinite(v) and v >= 0, name, f"must be finite and >= 0, got {v}")
        require(
            math.isfinite(self.relief_step_m) and self.relief_step_m > 0,
            "relief_step_m",
            f"must be finite and > 0, got {self.relief_step_m}",
        )


class TerrainClassifier:
    """Labels world-frame outlines with the terrain class under them (module docstring)."""

    def __init__(self, terrain, config: CauseConfig | None = None) -> None:
        self.config = config or CauseConfig()
        self.terrain = terrain
        track = terrain.track
        meta_config = terrain.metadata.get("config") if isinstance(terrain.metadata, dict) else None
        self._verge_m = tuple(
            float(getattr(b, "verge_width_m", 0.0))
            for b in (
                (meta_config.left_border, meta_config.right_border)
                if meta_config is not None
                else (None, None)
            )
        )
        self._borders = tuple(track.border_kinds)
        self._half_width = 0.5 * float(track.width_m)
        s = np.arange(-50.0, track.length_m + 50.0, 0.1)
        self._pts, yaw = track.pose_at(s)
        self._fwd = np.stack([-np.sin(yaw), np.cos(yaw)], axis=1)
        self._tree = cKDTree(self._pts)
        self._positives = [
            (_BESIDE.get(p.kind, "beside other"), np.asarray(p.footprint_xy_m, dtype=np.float64))
            for p in terrain.positive_obstacles
        ]

    def lateral_m(self, xy_m: np.ndarray) -> np.ndarray:
        """Signed offset (+ right of the driving direction) of world points (n, 2) from the centre line."""
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        _, k = self._tree.query(xy)
        rel = xy - self._pts[k]
        return rel[:, 0] * self._fwd[k, 1] - rel[:, 1] * self._fwd[k, 0]

    def classify(self, outline_world_xy_m: np.ndarray) -> str:
        """The class (one of :data:`CAUSES`) of a world-frame outline (N, 2)."""
        poly = np.asarray(outline_world_xy_m, dtype=np.float64).reshape(-1, 2)
        if poly.size == 0 or not np.all(np.isfinite(poly)):
            raise GeometryError("outline_world_xy_m: needs finite (N, 2) points")
        cfg = self.config
        centre = poly.mean(axis=0)
        probe = np.vstack([poly, centre[None]])
        for label, footprint in self._positives:
            ring = np.vstack([footprint, footprint[:1]])
            near = distance_to_polyline(probe, ring, cfg.positive_margin_m) <= cfg.positive_margin_m
            if near.any() or points_in_polygon(probe, footprint).any():
                return label
        lateral = float(self.lateral_m(centre)[0])
        beyond = abs(lateral) - self._half_width
        if beyond <= 0:
            return "track"
        side = 0 if lateral < 0 else 1
        if beyond <= self._verge_m[side]:
            return "verge"
        if self._borders[side] in _BORDER:
            return _BORDER[self._borders[side]]
        return "rough ground" if self.relief_m(poly) >= cfg.rough_relief_m else "other"

    def relief_m(self, outline_world_xy_m: np.ndarray) -> float:
        """Height span of the true ground over the outline's bounding box widened by the margin
        (0 where it lies off the heightfield)."""
        cfg = self.config
        lo = outline_world_xy_m.min(axis=0) - cfg.relief_margin_m
        hi = outline_world_xy_m.max(axis=0) + cfg.relief_margin_m
        xs = np.arange(lo[0], hi[0] + 1e-9, cfg.relief_step_m)
        ys = np.arange(lo[1], hi[1] + 1e-9, cfg.relief_step_m)
        z = self.terrain.heightfield.height_at(np.stack(np.meshgrid(xs, ys), axis=-1))
        z = z[np.isfinite(z)]
        return float(z.max() - z.min()) if z.size else 0.0


# -- figures -------------------------------------------------------------------------------------


def cause_bar_plot(causes: Mapping[str, Mapping[str, int]], km: float, path: str | Path) -> Path:
    """Grouped bars: false alarms per km of each terrain class, one bar per sensor mode."""
    plt = pyplot()
    modes = list(causes)
    labels = list(CAUSES)
    x = np.arange(len(labels))
    width = 0.8 / max(len(modes), 1)
    fig, ax = plt.subplots(figsize=(9, 4.5))
    for k, m in enumerate(modes):
        per_km = [causes[m].get(c, 0) / km if km > 0 else 0.0 for c in labels]
        ax.bar(x + (k - 0.5 * (len(modes) - 1)) * width, per_km, width, label=_MODE_LABELS.get(m, m))
    ax.set_xticks(x, labels, rotation=30, ha="right")
    ax.set_ylabel("false alarms per km")
    ax.set_title(f"False alarms by the true terrain under them ({km:.3f} km)")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_png(fig, path)


_MODE_LABELS = {"fused": "fused (HDL-64 + 2 HDL-32)", "hdl64": "HDL-64 only", "hdl32": "HDL-32 only"}


def frame_plot(terrain, frame, modes: Sequence[str], path: str | Path, title: str = "") -> Path:
    """One frame seen from above in the vehicle frame, one panel per sensor mode: the true ground
    height (shaded), the track edges, the true pits (green), positive obstacles (brown), the
    mode's returns (dots), its frame pairs (A->B, orange), its confirmed fused pairs (red) and its
    obstacles' outlines (blue where they match a truth or a track border, red where false alarms)."""
    plt = pyplot()
    grid = frame.detections[modes[0]].grid_spec
    centres = grid.cell_centres()
    world = frame.pose.to_world(
        np.concatenate([centres, np.zeros((*centres.shape[:-1], 1))], axis=-1).reshape(-1, 3)
    )
    height = terrain.heightfield.height_at(world[:, :2]).reshape(centres.shape[:-1]) - frame.pose.z
    x0, y0 = centres[..., 0].min(), centres[..., 1].min()
    x1, y1 = centres[..., 0].max(), centres[..., 1].max()
    fig, axes = plt.subplots(1, len(modes), figsize=(5.2 * len(modes), 7), squeeze=False)
    for ax, m in zip(axes[0], modes, strict=True):
        det = frame.detections[m]
        ax.imshow(height, origin="lower", extent=(x0, x1, y0, y1), cmap="terrain", alpha=0.55, aspect="equal")
        for name, scan in frame.scans.items():
            if name not in det.frame_pairs:
                continue
            p = np.asarray(scan.points_vehicle).reshape(-1, 3)
            p = p[np.isfinite(p).all(axis=1)]
            p = p[(p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)]
            ax.scatter(p[::3, 0], p[::3, 1], s=0.3, c="k", alpha=0.25, linewidths=0)
        for pairs in det.frame_pairs.values():
            for a, b in zip(pairs.a_m, pairs.b_m, strict=True):
                ax.plot([a[0], b[0]], [a[1], b[1]], color="orange", lw=0.8)
        ok = det.pairs.confirmed
        for a, b in zip(det.pairs.a_m[ok], det.pairs.b_m[ok], strict=True):
            ax.plot([a[0], b[0]], [a[1], b[1]], color="red", lw=1.2)
        line = frame.centre_line
        ax.plot(line[:, 0], line[:, 1], "w--", lw=0.8)
        for ob in terrain.positive_obstacles:
            fp = frame.pose.to_vehicle(
                np.column_stack([ob.footprint_xy_m, np.full(len(ob.footprint_xy_m), frame.pose.z)])
            )
            ax.fill(fp[:, 0], fp[:, 1], color="saddlebrown", alpha=0.7)
        for t in frame.truths:
            ax.fill(t[:, 0], t[:, 1], facecolor="none", edgecolor="green", lw=2)
        for ob in det.obstacles:
            o = np.asarray(ob.outline_xy_m)
            is_false = any(
                o is f or (o.shape == f.shape and np.array_equal(o, f))
                for f, _ in frame.judged.false_alarms[m]
            )
            ring = np.vstack([o, o[:1]])
            ax.plot(ring[:, 0], ring[:, 1], color="red" if is_false else "blue", lw=2)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        n_false = len(frame.judged.false_alarms[m])
        ax.set_title(f"{_MODE_LABELS.get(m, m)}: {len(det.obstacles)} obstacles, {n_false} false", fontsize=9)
        ax.set_xlabel("x right [m]")
    axes[0][0].set_ylabel("y forward [m]")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return save_png(fig, path)
