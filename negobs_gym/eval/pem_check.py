"""Check a PEM against the detector on courses it was not fitted on, side by side.

:func:`check_pem` drives fresh courses (:mod:`negobs_gym.eval.pem_data`) with the detector grid and
the PEM on the same poses and compares (:func:`compare`, from the CSVs alone):

- recall per 2 m bin from 6 to 20 m (a pit's centre distance, paper N §4.2; all sizes), checked
  in bins with at least ``min_sightings``; Table 7's layout (size x distance) in ``tables.md``;
- false alarms per km on and off the track (the detection campaign's count);
- the median near-edge offset of the drawn pits within 6-20 m;
- the first-confirmation distance (a pit's centre distance when first drawn), by the
  two-sample Kolmogorov-Smirnov statistic;
- cells drawn per pit (median of drawn / rim cells; reported, not checked).

Each figure is a ``key=value`` line; a check that fails (or cannot be made) makes the command
exit non-zero. The thresholds are :class:`PemCheckConfig`'s.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from negobs_gym.core.files import write_text_atomic
from negobs_gym.envs.pem import PerceptionErrorModel
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.campaign import RunOptions, read_csv
from negobs_gym.eval.pem_data import MODES, PemCampaignConfig, run_pem_campaign

__all__ = ["PemCheckConfig", "PemCheckResult", "check_pem", "compare"]


@dataclass(frozen=True, kw_only=True)
class PemCheckConfig:
    """Acceptance thresholds of a PEM check (issue 75's; not paper values)."""

    recall_edges_m: tuple[float, ...] = (6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0)  # paper N Table 7's
    max_recall_delta: float = 0.05
    min_sightings: int = 30  # a recall bin with fewer is reported, not checked
    max_false_alarm_ratio_delta: float = 0.25  # per km, PEM / detector - 1, on and off the track
    max_near_edge_delta_m: float = 0.1
    max_ks: float = 0.1
    size_edges_cells: tuple[int, ...] = (15, 20, 25, 30, 35, 40, 45, 56)  # paper N Table 7's rows

    def __post_init__(self) -> None:
        for name in ("max_recall_delta", "max_false_alarm_ratio_delta", "max_near_edge_delta_m", "max_ks"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, name, f"must be >= 0, got {value}")
        require(self.min_sightings >= 1, "min_sightings", "must be >= 1")


@dataclass(frozen=True)
class PemCheckResult:
    """The figures (``key`` -> value) and each check's verdict (``check_<name>`` -> passed)."""

    figures: dict[str, float]
    checks: dict[str, bool]
    recall_table: dict[str, list[list[float | None]]] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        return all(self.checks.values())

    def lines(self) -> list[str]:
        """``key=value`` lines: the figures, then the checks (``pass``/``fail``), then ``pem_check``."""
        out = [f"{k}={_fmt(v)}" for k, v in self.figures.items()]
        out += [f"{k}={'pass' if ok else 'fail'}" for k, ok in self.checks.items()]
        return [*out, f"pem_check={'pass' if self.passed else 'fail'}"]


def _fmt(value: float) -> str:
    return "nan" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.4g}"


def _label(lo: float, hi: float) -> str:
    return f"{lo:g}_{hi:g}m"


def _first_confirmations(rows: list[dict[str, str]]) -> np.ndarray:
    """Per pit and course, its centre distance in the first frame it was drawn."""
    first: dict[tuple[str, str], tuple[int, float]] = {}
    for r in rows:
        if r["detected"] != "1":
            continue
        key, frame = (r["episode"], r["obstacle"]), int(r["frame"])
        if key not in first or frame < first[key][0]:
            first[key] = (frame, float(r["centre_m"]))
    return np.array([d for _, d in first.values()])


def compare(
    sightings_csv: str | Path, frames_csv: str | Path, config: PemCheckConfig | None = None
) -> PemCheckResult:
    """The detector's and the PEM's figures side by side and the checks (module docstring)."""
    from scipy.stats import ks_2samp

    cfg = config or PemCheckConfig()
    sightings, frames = read_csv(sightings_csv), read_csv(frames_csv)
    by_mode = {m: [r for r in sightings if r["mode"] == m] for m in MODES}
    frames_by = {m: [r for r in frames if r["mode"] == m] for m in MODES}
    if not frames_by["pem"]:
        raise ConfigError("frames", f"{frames_csv} holds no PEM frame: drive with a PEM to compare")
    figures: dict[str, float] = {}
    checks: dict[str, bool] = {}
    edges = np.asarray(cfg.recall_edges_m)
    recall_ok = True
    for m in MODES:
        figures[f"frames_{m}"] = float(len(frames_by[m]))
    for j in range(len(edges) - 1):
        lo, hi = edges[j], edges[j + 1]
        rates, seen = {}, 0
        for m in MODES:
            inside = [r for r in by_mode[m] if lo <= float(r["centre_m"]) < hi]
            seen = len(inside)
            rates[m] = sum(r["detected"] == "1" for r in inside) / seen if seen else math.nan
            figures[f"recall_{_label(lo, hi)}_{m}"] = rates[m]
        figures[f"sightings_{_label(lo, hi)}"] = float(seen)
        delta = rates["pem"] - rates["detector"]
        figures[f"recall_{_label(lo, hi)}_delta"] = delta
        if seen >= cfg.min_sightings:
            recall_ok &= abs(delta) <= cfg.max_recall_delta
    checks["check_recall"] = recall_ok
    for side in ("on", "off"):
        per_km = {}
        for m in MODES:
            km = sum(float(r["travelled_m"]) for r in frames_by[m]) / 1000.0
            count = sum(int(r[f"false_alarms_{side}"]) for r in frames_by[m])
            per_km[m] = count / km if km > 0 else math.nan
            figures[f"false_alarms_per_km_{side}_track_{m}"] = per_km[m]
        det, pem = per_km["detector"], per_km["pem"]
        if det > 0:
            ratio = pem / det - 1.0
            ok = abs(ratio) <= cfg.max_false_alarm_ratio_delta
        else:
            ratio, ok = (0.0, True) if pem == 0 else (math.inf, False)
        figures[f"false_alarms_per_km_{side}_track_ratio_delta"] = ratio
        checks[f"check_false_alarms_{side}_track"] = bool(ok)
    medians = {}
    for m in MODES:
        offsets = [
            float(r["near_offset_m"])
            for r in by_mode[m]
            if r["detected"] == "1" and edges[0] <= float(r["centre_m"]) < edges[-1]
        ]
        medians[m] = float(np.median(offsets)) if offsets else math.nan
        figures[f"near_edge_offset_median_m_{m}"] = medians[m]
        ratios = [int(r["drawn_cells"]) / int(r["cells"]) for r in by_mode[m] if r["detected"] == "1"]
        figures[f"drawn_cells_per_rim_cell_median_{m}"] = float(np.median(ratios)) if ratios else math.nan
    near_delta = medians["pem"] - medians["detector"]
    figures["near_edge_offset_median_delta_m"] = near_delta
    checks["check_near_edge"] = bool(abs(near_delta) <= cfg.max_near_edge_delta_m)  # NaN fails
    first = {m: _first_confirmations(by_mode[m]) for m in MODES}
    for m in MODES:
        figures[f"first_confirmation_median_m_{m}"] = (
            float(np.median(first[m])) if first[m].size else math.nan
        )
        figures[f"first_confirmations_{m}"] = float(first[m].size)
    ks = (
        float(ks_2samp(first["detector"], first["pem"]).statistic)
        if all(f.size for f in first.values())
        else math.nan
    )
    figures["ks_first_confirmation"] = ks
    checks["check_first_confirmation_ks"] = bool(ks <= cfg.max_ks)
    return PemCheckResult(figures, checks, _recall_tables(by_mode, cfg))


def _recall_tables(
    by_mode: dict[str, list[dict[str, str]]], cfg: PemCheckConfig
) -> dict[str, list[list[float | None]]]:
    """Per grid, recall by size (Table 7's rows) and distance (its columns); None where unseen."""
    s_edges, d_edges = np.asarray(cfg.size_edges_cells), np.asarray(cfg.recall_edges_m)
    out = {}
    for m, rows in by_mode.items():
        seen = np.zeros((len(s_edges) - 1, len(d_edges) - 1))
        hit = np.zeros_like(seen)
        for r in rows:
            s = np.digitize(int(r["cells"]), s_edges) - 1
            d = np.digitize(float(r["centre_m"]), d_edges) - 1
            if 0 <= s < seen.shape[0] and 0 <= d < seen.shape[1]:
                seen[s, d] += 1
                hit[s, d] += r["detected"] == "1"
        out[m] = [
            [(float(h / n) if n else None) for h, n in zip(hr, nr, strict=True)]
            for hr, nr in zip(hit, seen, strict=True)
        ]
        out[f"{m}_sightings"] = seen.astype(int).tolist()
    return out


def _markdown(result: PemCheckResult, cfg: PemCheckConfig) -> str:
    from negobs_gym.eval.tables import bin_labels

    dist = bin_labels(np.asarray(cfg.recall_edges_m), " m")
    sizes = bin_labels(np.asarray(cfg.size_edges_cells))
    parts = ["# PEM check: detector vs PEM on fresh courses", "## Recall by distance (all sizes)"]
    parts.append("| distance | sightings | detector | PEM | Δ |\n|---|---|---|---|---|")
    for j, label in enumerate(dist):
        lo, hi = cfg.recall_edges_m[j], cfg.recall_edges_m[j + 1]
        f = result.figures
        k = _label(lo, hi)
        parts[-1] += (
            f"\n| {label} | {f[f'sightings_{k}']:.0f} | {_fmt(f[f'recall_{k}_detector'])} | "
            f"{_fmt(f[f'recall_{k}_pem'])} | {_fmt(f[f'recall_{k}_delta'])} |"
        )
    for m in MODES:
        parts.append(f"## Recall by size x distance, {m} (paper N Table 7 layout)")
        head = "| cells | " + " | ".join(dist) + " |\n|---|" + "---|" * len(dist)
        body = [
            f"| {sizes[i]} | " + " | ".join("-" if v is None else f"{v:.2f}" for v in row) + " |"
            for i, row in enumerate(result.recall_table[m])
        ]
        parts.append("\n".join([head, *body]))
    parts.append("## Every figure and check\n\n```\n" + "\n".join(result.lines()) + "\n```")
    return "\n\n".join(parts) + "\n"


def _plots(sightings_csv: Path, result: PemCheckResult, cfg: PemCheckConfig, out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from negobs_gym.core.files import atomic_target

    rows = read_csv(sightings_csv)
    written = []
    edges = np.asarray(cfg.recall_edges_m)
    mids = 0.5 * (edges[1:] + edges[:-1])
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for m, style in zip(MODES, ("o-", "s--"), strict=True):
        axes[0].plot(
            mids,
            [result.figures[f"recall_{_label(a, b)}_{m}"] for a, b in itertools.pairwise(edges)],
            style,
            label=m,
        )
        first = np.sort(_first_confirmations([r for r in rows if r["mode"] == m]))
        if first.size:
            axes[1].step(first, np.arange(1, first.size + 1) / first.size, where="post", label=m)
        near = [float(r["near_offset_m"]) for r in rows if r["mode"] == m and r["detected"] == "1"]
        if near:
            axes[2].hist(near, bins=np.arange(-3.0, 3.01, 0.2), histtype="step", density=True, label=m)
    axes[0].set(xlabel="pit centre distance [m]", ylabel="recall", ylim=(0, 1.05), title="recall, all sizes")
    axes[1].set(
        xlabel="first-confirmation distance [m]", ylabel="share of pits", title="first confirmation (ECDF)"
    )
    axes[2].set(xlabel="drawn minus true near edge [m]", ylabel="density", title="near-edge offset")
    for ax in axes:
        ax.legend()
        ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_target(out / "pem_check.png") as tmp:
        fig.savefig(tmp, format="png", dpi=90)
    plt.close(fig)
    written.append(out / "pem_check.png")
    return written


def check_pem(
    model: PerceptionErrorModel,
    config: PemCampaignConfig,
    out_dir: str | Path,
    check: PemCheckConfig | None = None,
    options: RunOptions | None = None,
) -> PemCheckResult:
    """Drive ``config``'s courses with the detector and ``model`` side by side, compare and write
    ``check.txt`` (the ``key=value`` lines), ``summary.json``, ``tables.md`` and ``pem_check.png``
    to ``out_dir``.

    Raises:
        ConfigError: a course the model was fitted on (field ``first_seed``).
    """
    fit = model.fit
    if "first_seed" in fit and "seeds" in fit:
        fitted = set(range(int(fit["first_seed"]), int(fit["first_seed"]) + int(fit["seeds"])))
        used = sorted(fitted & set(config.seed_list))
        require(
            not used,
            "first_seed",
            f"seeds {used[:5]}{'...' if len(used) > 5 else ''} were used to fit the PEM; check on fresh "
            f"ones (the fit drove seeds {min(fitted)}-{max(fitted)})",
        )
    cfg = check or PemCheckConfig()
    out = Path(out_dir)
    csvs = run_pem_campaign(config, out, model, options, "PEM check courses")
    result = compare(csvs["sightings"], csvs["frames"], cfg)
    write_text_atomic(out / "check.txt", "\n".join(result.lines()) + "\n")
    summary = {
        "figures": result.figures,
        "checks": result.checks,
        "recall_table": result.recall_table,
        "thresholds": asdict(cfg),
    }
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=1, sort_keys=True, default=str) + "\n")
    write_text_atomic(out / "tables.md", _markdown(result, cfg))
    _plots(csvs["sightings"], result, cfg, out)
    return result
