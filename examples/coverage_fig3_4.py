"""Paper N Fig. 3/4: top-down points of the top HDL-64 alone vs. the two side HDL-32s.

Flat ground with a 1 x 1 x 0.8 m pit centred 8 m ahead, noise off. Left panel: the HDL-64E S2's
rings (calibrated table), with the ring gap at 8/10/15 m from paper N Eq. 3 and as measured.
Right panel: the side HDL-32Es (rolled 90 deg), whose lasers sweep radially, with their radial
point spacing at 10 m. The pit shows as a gap in the HDL-64 rings and as a jump along the HDL-32
lines. Writes a PNG atomically.

Run: ``python examples/coverage_fig3_4.py --out outputs/coverage_fig3_4.png [--backend auto]``
"""

from __future__ import annotations

import argparse
import os
import tempfile
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.detector.geometry import nadir_angle_from_elevation, radial_resolution, ring_radius
from negobs_gym.sensors import NoiseConfig, paper_n_rig
from negobs_gym.sensors.lidar import scan
from negobs_gym.sensors.raycast import make_caster
from negobs_gym.sim.presets import braking_track
from negobs_gym.sim.world import World

X_HALF_M, Y_MAX_M = 6.0, 20.0  # plotted area ahead of the vehicle [m]


def ring_gaps_m(elevation_rad: np.ndarray, height_m: float, at_m: tuple[float, ...]) -> dict[float, float]:
    """Eq. 3 ring gap between the two lasers whose flat-ground rings bracket each distance."""
    beta = nadir_angle_from_elevation(elevation_rad)
    radii = ring_radius(height_m, beta)
    order = np.argsort(radii)
    radii, beta = radii[order], beta[order]
    gaps = {}
    for d in at_m:
        k = int(np.clip(np.searchsorted(radii, d), 1, len(radii) - 1))
        gaps[d] = float(radial_resolution(height_m, beta[k], beta[k] - beta[k - 1]))
    return gaps


def measured_ring_gap_m(points: np.ndarray, at_m: float) -> float:
    """Gap between measured ring radii straight ahead (|x| < 0.3 m) around ``at_m``."""
    ahead = (np.abs(points[..., 0]) < 0.3) & (points[..., 1] > 0) & (np.abs(points[..., 2]) < 0.05)
    with warnings.catch_warnings():  # lasers with no ground point ahead give an all-NaN row
        warnings.simplefilter("ignore", RuntimeWarning)
        r = np.nanmedian(np.where(ahead, points[..., 1], np.nan), axis=1)
    r = np.sort(r[np.isfinite(r)])
    k = int(np.clip(np.searchsorted(r, at_m), 1, len(r) - 1))
    return float(r[k] - r[k - 1])


def side_spacing_m(points: np.ndarray, at_m: float) -> float:
    """Median radial spacing of consecutive ground points along the side lasers near ``at_m``."""
    y = np.where(
        (np.abs(points[..., 2]) < 0.05) & (np.abs(points[..., 1] - at_m) < 1.0), points[..., 1], np.nan
    )
    y = np.sort(y, axis=1)
    return float(np.nanmedian(np.diff(y, axis=1)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("outputs/coverage_fig3_4.png"))
    parser.add_argument("--backend", default="auto", choices=["auto", "embree", "pybullet"])
    args = parser.parse_args()

    # braking_track: ditch near edge at 7.5 m, 1 m long, 1 m wide, 0.8 m deep -> centre at 8 m
    terrain = braking_track(ditch_distance_m=7.5, ditch_length_m=1.0, ditch_width_m=1.0, rough=False)
    rig = paper_n_rig()
    off = NoiseConfig(enabled=False)
    with World(terrain) as world:
        caster = make_caster(world, backend=args.backend)
        pose = Pose()
        scans = {m.name: scan(m, caster, pose, noise=off) for m in rig.mounts}
    p64 = scans["hdl64"].points_vehicle
    p32 = np.concatenate([scans["hdl32_left"].points_vehicle, scans["hdl32_right"].points_vehicle], axis=0)
    h64 = rig.mount("hdl64").translation_m[2]
    eq3 = ring_gaps_m(scans["hdl64"].elevation_rad, h64, (8.0, 10.0, 15.0))
    gap10 = measured_ring_gap_m(p64, 10.0)
    sp10 = side_spacing_m(p32, 10.0)
    print(f"HDL-64 ring gap (Eq. 3): {', '.join(f'{d:.0f} m: {g:.2f} m' for d, g in eq3.items())}")
    print(
        f"HDL-64 measured ring gap at 10 m: {gap10:.2f} m; side HDL-32 radial spacing at 10 m: {sp10:.3f} m"
    )

    fig, axes = plt.subplots(1, 2, figsize=(11, 8), sharey=True)
    outline = terrain.negative_obstacles[0].outline_xy_m
    for ax, pts, title in (
        (axes[0], p64, "top HDL-64E S2 alone (paper N Fig. 3)"),
        (axes[1], p32, "two side HDL-32E, rolled 90 deg (paper N Fig. 4)"),
    ):
        q = pts.reshape(-1, 3)
        keep = np.isfinite(q).all(axis=1) & (np.abs(q[:, 0]) < X_HALF_M) & (q[:, 1] > 0) & (q[:, 1] < Y_MAX_M)
        q = q[keep]
        sc = ax.scatter(
            q[:, 0], q[:, 1], s=0.3, c=q[:, 2], cmap="viridis", vmin=-0.8, vmax=0.0, rasterized=True
        )
        ax.fill(outline[:, 0], outline[:, 1], fill=False, ec="red", lw=1.2, label="pit 1 x 1 x 0.8 m")
        ax.set_title(title)
        ax.set_xlabel("x (right) [m]")
        ax.set_xlim(-X_HALF_M, X_HALF_M)
        ax.set_ylim(0, Y_MAX_M)
        ax.set_aspect("equal")
        ax.legend(loc="upper right")
    axes[0].set_ylabel("y (forward) [m]")
    for d, g in eq3.items():
        axes[0].annotate(
            f"ring gap {g:.2f} m (Eq. 3)", (X_HALF_M - 0.2, d), ha="right", va="bottom", fontsize=8
        )
        axes[0].axhline(d, color="grey", lw=0.4, ls=":")
    axes[1].annotate(
        f"radial spacing at 10 m: {sp10:.3f} m\n(HDL-64 ring gap there: {gap10:.2f} m)",
        (X_HALF_M - 0.2, 10.0),
        ha="right",
        va="bottom",
        fontsize=8,
    )
    axes[1].axhline(10.0, color="grey", lw=0.4, ls=":")
    fig.colorbar(sc, ax=axes, shrink=0.6, label="point z (vehicle frame) [m]")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=args.out.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=120)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the file the usual mode
        os.replace(tmp, args.out)  # atomic write
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    plt.close(fig)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
