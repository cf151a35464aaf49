"""Campaign figures (matplotlib, Agg backend), each written atomically as PNG."""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from negobs_gym.core.files import write_bytes_atomic

MODE_LABELS = {"fused": "fused (HDL-64 + 2 HDL-32)", "hdl64": "HDL-64 only", "hdl32": "HDL-32 only"}
# distinct line styles and markers: equal curves (e.g. fused = HDL-64 only) stay visible
MODE_STYLES = {
    "fused": {"linestyle": "-", "marker": "o", "linewidth": 3.0, "alpha": 0.6, "markersize": 9},
    "hdl64": {"linestyle": "-.", "marker": "^", "linewidth": 1.5},
    "hdl32": {"linestyle": ":", "marker": "v", "linewidth": 1.5},
}


def pyplot():
    """matplotlib.pyplot on the Agg backend (imported when a figure is drawn)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_png(fig, path: str | Path) -> Path:
    """``fig`` as a PNG at ``path``, written atomically; the figure is closed."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    return write_bytes_atomic(path, buffer.getvalue())


def _bin_centres(distance_bins: Sequence[str]) -> np.ndarray:
    edges = [tuple(float(v) for v in b.removesuffix(" m").split("-")) for b in distance_bins]
    return np.array([0.5 * (lo + hi) for lo, hi in edges])


def fig16_plot(
    curves: Mapping[str, Sequence[float | None]],
    paper_fused: Sequence[float],
    distance_bins: Sequence[str],
    path: str | Path,
) -> Path:
    """Paper N Fig. 16: recall of 25-34-cell obstacles vs distance per sensor mode, paper's fused dashed."""
    plt = pyplot()
    x = _bin_centres(distance_bins)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(x, paper_fused, "k--", marker="s", label="paper N fused (Table 6/7, 25-34 cells)")
    for mode, values in curves.items():
        y = np.array([np.nan if v is None else v for v in values], dtype=float)
        style = MODE_STYLES.get(mode, {"marker": "o"})
        ax.plot(x, y, label=f"ours: {MODE_LABELS.get(mode, mode)}", **style)
    ax.set_xticks(x, distance_bins, rotation=30)
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("distance of the obstacle centre from the INS origin")
    ax.set_ylabel("recall")
    ax.set_title("Recall of 25-34-cell negative obstacles (paper N Fig. 16 layout)")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    return save_png(fig, path)


def recall_heatmap(
    ours: np.ndarray,
    paper: np.ndarray,
    occurrences: np.ndarray,
    size_bins: Sequence[str],
    distance_bins: Sequence[str],
    path: str | Path,
) -> Path:
    """Recall per size x distance bin, ours (with counts) beside paper N's Table 7."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharey=True, layout="constrained")
    for ax, values, title, counts in (
        (axes[0], np.asarray(ours, dtype=float), "ours (fused), n = occurrences", occurrences),
        (axes[1], np.asarray(paper, dtype=float), "paper N Table 7", None),
    ):
        image = ax.imshow(np.ma.masked_invalid(values), vmin=0.0, vmax=1.0, cmap="viridis", origin="lower")
        for (i, j), v in np.ndenumerate(values):
            if np.isnan(v):
                ax.text(j, i, "-", ha="center", va="center", color="grey")
                continue
            label = f"{v:.2f}" if counts is None else f"{v:.2f}\nn={int(counts[i][j])}"
            ax.text(j, i, label, ha="center", va="center", fontsize=7, color="white" if v < 0.6 else "black")
        ax.set_xticks(range(len(distance_bins)), distance_bins, rotation=30)
        ax.set_yticks(range(len(size_bins)), size_bins)
        ax.set_xlabel("distance of the obstacle centre")
        ax.set_title(title)
    axes[0].set_ylabel("obstacle size [20 cm cells]")
    fig.colorbar(image, ax=axes, shrink=0.9, label="recall")
    return save_png(fig, path)


def distribution_plot(
    samples: Mapping[str, Sequence[float]], xlabel: str, title: str, path: str | Path
) -> Path:
    """One box per configuration (label -> samples), empty configurations shown as such."""
    plt = pyplot()
    labels = list(samples)
    fig, ax = plt.subplots(figsize=(9, 0.45 * len(labels) + 1.8), layout="constrained")
    data = [np.asarray(samples[k], dtype=float) for k in labels]
    positions = np.arange(len(labels))
    filled = [i for i, d in enumerate(data) if d.size]
    if filled:
        import matplotlib

        major, minor = (int(v) for v in matplotlib.__version__.split(".")[:2])
        # matplotlib 3.10 renamed vert=False to orientation="horizontal" (and deprecated vert)
        horizontal = {"orientation": "horizontal"} if (major, minor) >= (3, 10) else {"vert": False}
        ax.boxplot([data[i] for i in filled], positions=positions[filled], widths=0.6, **horizontal)
    for i, d in enumerate(data):
        if d.size:  # every sample as a dot: small campaigns have too few for a box
            ax.plot(d, np.full(d.size, i), "o", color="tab:blue", alpha=0.5, markersize=4)
        else:
            ax.text(
                0.01, i, "none", va="center", color="grey", fontsize=8, transform=ax.get_yaxis_transform()
            )
    ax.set_yticks(positions, [f"{k} (n={d.size})" for k, d in zip(labels, data, strict=True)], fontsize=8)
    ax.set_ylim(-0.7, len(labels) - 0.3)
    ax.set_xlabel(xlabel)
    ax.set_title(title)
    ax.grid(axis="x", alpha=0.3)
    return save_png(fig, path)


def learning_curves_plot(runs: Mapping[str, Path | str], path: str | Path) -> Path:
    """Training curves of ``negobs train`` runs (label -> output folder): SB3's
    ``rollout/ep_rew_mean`` against env steps (from every ``logs/*/progress.csv``), and the
    evaluation's goal share (``eval.csv``) as markers. Runs without logs are skipped."""
    import csv

    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 6.0), sharex=True)
    for label, folder in runs.items():
        folder = Path(folder)
        steps, reward = [], []
        for log in sorted((folder / "logs").glob("*/progress.csv"), key=lambda p: int(p.parent.name)):
            with log.open(newline="") as fh:
                for row in csv.DictReader(fh):
                    if row.get("rollout/ep_rew_mean"):
                        steps.append(int(row["time/total_timesteps"]))
                        reward.append(float(row["rollout/ep_rew_mean"]))
        (line,) = top.plot(steps, reward, label=label)
        evaluation = folder / "eval.csv"
        if evaluation.exists():
            with evaluation.open(newline="") as fh:
                rows = list(csv.DictReader(fh))
            bottom.plot(
                [int(r["step"]) for r in rows],
                [int(r["goal"]) / int(r["episodes"]) for r in rows],
                marker="o",
                color=line.get_color(),
                label=label,
            )
    top.set_ylabel("training episode return\n(rollout/ep_rew_mean)")
    top.grid(alpha=0.3)
    top.legend(fontsize=8)
    bottom.set_ylabel("goal reached\n(evaluation, unseen seeds)")
    bottom.set_xlabel("env steps")
    bottom.set_ylim(-0.05, 1.05)
    bottom.grid(alpha=0.3)
    return save_png(fig, path)
