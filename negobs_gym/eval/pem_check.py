"""Check a PEM against the detector on courses it was not fitted on, side by side.

:func:`check_pem` drives fresh courses (:mod:`negobs_gym.eval.pem_data`) with the detector grid and
the PEM on the same poses and compares each channel the PEM draws (:func:`compare`, from the CSVs
alone; the ``positive`` channel's figures and checks are prefixed ``positive_``, its obstacles'
centre distance and footprint cells take the pits' places):

- recall per 2 m bin from 6 to 20 m (a pit's centre distance, paper N §4.2; all sizes), checked
  in bins with at least ``min_sightings``; Table 7's layout (size x distance) in ``tables.md``;
- false alarms per km on and off the track (the detection campaign's count), with the alarm-frames
  counted (a rate of a handful cannot be read to 25 %);
- the median near-edge offset of the drawn pits within 6-20 m;
- the first-confirmation distance (a pit's centre distance when first drawn), by the
  two-sample Kolmogorov-Smirnov statistic;
- cells drawn per pit (median of drawn / rim cells; reported, not checked);
- false alarms per km per course: their spread and a course-resampled interval (reported).

:func:`check_braking` is the closed loop: the braking campaign (the reckless driver behind the
Eq. 18 safety filter) once on the detector grid and once on the PEM's, ``stopped_before`` counts
and median stop margins side by side (the first-veto gaps reported). :func:`check_policy` closes
it on a trained policy: the same unseen seeds on both grids, goals, entries, collisions and vetoes
side by side, and the transfer gap in goal rate checked.

Each figure is a ``key=value`` line; a check that fails (or cannot be made) makes the command
exit non-zero. The thresholds are :class:`PemCheckConfig`'s.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym.core.files import write_text_atomic
from negobs_gym.envs.pem import PerceptionErrorModel
from negobs_gym.errors import ConfigError, require
from negobs_gym.eval.campaign import RunOptions, read_csv
from negobs_gym.eval.pem_data import CHANNEL_TABLES, MODES, PemCampaignConfig, pem_digest, run_pem_campaign

__all__ = [
    "BrakingCheckConfig",
    "PemCheckConfig",
    "PemCheckResult",
    "PolicyCheckConfig",
    "check_braking",
    "check_pem",
    "check_policy",
    "compare",
    "compare_braking",
    "compare_policy",
]


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
    spread_confidence: float = 0.9  # of the courses' false-alarm intervals (reported, not checked)
    bootstrap_resamples: int = 2000

    def __post_init__(self) -> None:
        for name in ("max_recall_delta", "max_false_alarm_ratio_delta", "max_near_edge_delta_m", "max_ks"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, name, f"must be >= 0, got {value}")
        require(self.min_sightings >= 1, "min_sightings", "must be >= 1")
        require(0 < self.spread_confidence < 1, "spread_confidence", "must lie in (0, 1)")
        require(self.bootstrap_resamples >= 1, "bootstrap_resamples", "must be >= 1")


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
            figures[f"false_alarms_{side}_track_count_{m}"] = float(count)  # alarm-frames: a rate's weight
        det, pem = per_km["detector"], per_km["pem"]
        if det > 0:
            ratio = pem / det - 1.0
            ok = abs(ratio) <= cfg.max_false_alarm_ratio_delta
        else:
            ratio, ok = (0.0, True) if pem == 0 else (math.inf, False)
        figures[f"false_alarms_per_km_{side}_track_ratio_delta"] = ratio
        checks[f"check_false_alarms_{side}_track"] = bool(ok)
        figures.update(_course_spread(frames_by, side, cfg))
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


def _course_spread(
    frames_by: dict[str, list[dict[str, str]]], side: str, cfg: PemCheckConfig
) -> dict[str, float]:
    """How far the courses' false alarms per km spread: per grid the courses' lowest, median and
    highest rate and the 90 % interval of the pooled rate resampling whole courses (a cluster
    bootstrap: one course's frames share its clutter), and the interval of PEM / detector - 1."""
    key = f"false_alarms_per_km_{side}_track"
    courses = sorted({r["seed"] for r in frames_by["detector"]})  # a course's grids are episodes of its seed
    counts = np.zeros((len(MODES), len(courses)))
    km = np.zeros_like(counts)
    index = {c: i for i, c in enumerate(courses)}
    for j, m in enumerate(MODES):
        for r in frames_by[m]:
            i = index.get(r["seed"])
            if i is not None:
                counts[j, i] += int(r[f"false_alarms_{side}"])
                km[j, i] += float(r["travelled_m"]) / 1000.0
    out = {f"{key}_courses": float(len(courses))}
    with np.errstate(invalid="ignore", divide="ignore"):
        for j, m in enumerate(MODES):
            rates = counts[j] / km[j]
            out[f"{key}_course_min_{m}"] = float(np.nanmin(rates)) if len(courses) else math.nan
            out[f"{key}_course_median_{m}"] = float(np.nanmedian(rates)) if len(courses) else math.nan
            out[f"{key}_course_max_{m}"] = float(np.nanmax(rates)) if len(courses) else math.nan
        if len(courses) < 2:
            return out
        rng = np.random.default_rng(0)
        picks = rng.integers(len(courses), size=(cfg.bootstrap_resamples, len(courses)))
        pooled = counts[:, picks].sum(axis=2) / km[:, picks].sum(axis=2)  # (modes, resamples)
        ratio = pooled[1] / pooled[0] - 1.0
    lo, hi = 50.0 - 50.0 * cfg.spread_confidence, 50.0 + 50.0 * cfg.spread_confidence
    for j, m in enumerate(MODES):
        out[f"{key}_{m}_lo"], out[f"{key}_{m}_hi"] = (float(v) for v in np.nanpercentile(pooled[j], [lo, hi]))
    finite = ratio[np.isfinite(ratio)]
    out[f"{key}_ratio_delta_lo"], out[f"{key}_ratio_delta_hi"] = (
        (float(v) for v in np.percentile(finite, [lo, hi])) if finite.size else (math.nan, math.nan)
    )
    return out


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


def _with_prefix(result: PemCheckResult, prefix: str) -> PemCheckResult:
    """``result`` with ``prefix`` before each figure's and table's name and after each check's ``check_``."""
    return PemCheckResult(
        {f"{prefix}{k}": v for k, v in result.figures.items()},
        {k.replace("check_", f"check_{prefix}", 1): ok for k, ok in result.checks.items()},
        {f"{prefix}{k}": v for k, v in result.recall_table.items()},
    )


def _merged(*results: PemCheckResult) -> PemCheckResult:
    """One result of several (their names must differ)."""
    figures, checks, tables = {}, {}, {}
    for r in results:
        figures.update(r.figures)
        checks.update(r.checks)
        tables.update(r.recall_table)
    return PemCheckResult(figures, checks, tables)


def _markdown(result: PemCheckResult, cfg: PemCheckConfig, prefixes: tuple[str, ...] = ("",)) -> str:
    from negobs_gym.eval.tables import bin_labels

    dist = bin_labels(np.asarray(cfg.recall_edges_m), " m")
    sizes = bin_labels(np.asarray(cfg.size_edges_cells))
    parts = ["# PEM check: detector vs PEM on fresh courses"]
    for prefix in prefixes:
        what = "pits" if not prefix else "positive obstacles"
        parts.append(f"## Recall by distance (all sizes), {what}")
        parts.append("| distance | sightings | detector | PEM | Δ |\n|---|---|---|---|---|")
        f = result.figures
        for j, label in enumerate(dist):
            k = _label(cfg.recall_edges_m[j], cfg.recall_edges_m[j + 1])
            cells = (
                f"{f[f'{prefix}sightings_{k}']:.0f}",
                *(_fmt(f[f"{prefix}recall_{k}_{c}"]) for c in (*MODES, "delta")),
            )
            parts[-1] += f"\n| {label} | " + " | ".join(cells) + " |"
        for m in MODES:
            parts.append(f"## Recall by size x distance, {what}, {m} (paper N Table 7 layout)")
            head = "| cells | " + " | ".join(dist) + " |\n|---|" + "---|" * len(dist)
            body = [
                f"| {sizes[i]} | " + " | ".join("-" if v is None else f"{v:.2f}" for v in row) + " |"
                for i, row in enumerate(result.recall_table[f"{prefix}{m}"])
            ]
            parts.append("\n".join([head, *body]))
    parts.append("## Every figure and check\n\n```\n" + "\n".join(result.lines()) + "\n```")
    return "\n\n".join(parts) + "\n"


def _plots(
    sightings_csv: Path, result: PemCheckResult, cfg: PemCheckConfig, out: Path, prefix: str = ""
) -> list[Path]:
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
            [result.figures[f"{prefix}recall_{_label(a, b)}_{m}"] for a, b in itertools.pairwise(edges)],
            style,
            label=m,
        )
        first = np.sort(_first_confirmations([r for r in rows if r["mode"] == m]))
        if first.size:
            axes[1].step(first, np.arange(1, first.size + 1) / first.size, where="post", label=m)
        near = [float(r["near_offset_m"]) for r in rows if r["mode"] == m and r["detected"] == "1"]
        if near:
            axes[2].hist(near, bins=np.arange(-3.0, 3.01, 0.2), histtype="step", density=True, label=m)
    what = "pit" if not prefix else "obstacle"
    axes[0].set(
        xlabel=f"{what} centre distance [m]",
        ylabel="recall",
        ylim=(0, 1.05),
        title=f"{what}s: recall, all sizes",
    )
    axes[1].set(
        xlabel="first-confirmation distance [m]",
        ylabel=f"share of {what}s",
        title="first confirmation (ECDF)",
    )
    axes[2].set(xlabel="drawn minus true near edge [m]", ylabel="density", title="near-edge offset")
    for ax in axes:
        if ax.get_legend_handles_labels()[0]:  # a panel with nothing drawn (no detection) has none
            ax.legend()
        ax.grid(alpha=0.3)
    fig.tight_layout()
    name = f"pem_check{'_' + prefix.rstrip('_') if prefix else ''}.png"
    with atomic_target(out / name) as tmp:
        fig.savefig(tmp, format="png", dpi=90)
    plt.close(fig)
    written.append(out / name)
    return written


def check_pem(
    model: PerceptionErrorModel,
    config: PemCampaignConfig,
    out_dir: str | Path,
    check: PemCheckConfig | None = None,
    options: RunOptions | None = None,
) -> PemCheckResult:
    """Drive ``config``'s courses with the detector and ``model`` side by side, compare and write
    ``check.txt`` (the ``key=value`` lines), ``summary.json``, ``tables.md``, ``pem_check.png`` and
    (the positive channel's) ``pem_check_positive.png`` to ``out_dir``.

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
    prefixes = {c: ("" if c == "negative" else f"{c}_") for c in model.channels}
    results = {
        c: _with_prefix(
            compare(csvs[CHANNEL_TABLES[c]["sightings"]], csvs[CHANNEL_TABLES[c]["frames"]], cfg), p
        )
        for c, p in prefixes.items()
    }
    result = _merged(*results.values())
    write_text_atomic(out / "check.txt", "\n".join(result.lines()) + "\n")
    summary = {
        "figures": result.figures,
        "checks": result.checks,
        "recall_table": result.recall_table,
        "thresholds": asdict(cfg),
    }
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=1, sort_keys=True, default=str) + "\n")
    write_text_atomic(out / "tables.md", _markdown(result, cfg, tuple(prefixes.values())))
    for c, prefix in prefixes.items():
        _plots(csvs[CHANNEL_TABLES[c]["sightings"]], result, cfg, out, prefix)
    return result


def _mode_options(
    out_dir: Path, mode: str, model_path: str | Path | None, options: RunOptions | None
) -> RunOptions | None:
    """``options`` for one grid's closed-loop campaign in ``out_dir``: the PEM's resumes only the
    episodes of the same model file and PEM code (:func:`~negobs_gym.eval.pem_data.pem_digest`, kept
    beside them), as its path may hold a refit. ``model_path`` None: every shipped file counts."""
    from negobs_gym.envs.pem import SHIPPED_PEM_PATHS

    if mode != "pem" or options is None or not options.resume:
        return options
    files = [Path(model_path)] if model_path is not None else sorted(set(SHIPPED_PEM_PATHS.values()))
    digest = pem_digest("".join(f.read_text(encoding="utf-8") for f in files))
    marker = out_dir / "pem_digest.txt"
    same = marker.is_file() and marker.read_text(encoding="utf-8").strip() == digest
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text_atomic(marker, digest + "\n")
    return options if same else replace(options, resume=False)


def grid_overrides(model_path: str | Path | None) -> dict[str, tuple[str, ...]]:
    """The ``--set`` assignments of each grid a closed loop compares, by mode: the detector's and
    the PEM ``model_path``'s (None: ``observation.pem_model`` stays unset, so each run draws from
    the shipped model of its own ``positive`` channel, :func:`~negobs_gym.envs.pem.shipped_pem_path`)."""
    pem = ("observation.source=pem",)
    if model_path is not None:
        pem += (f"observation.pem_model={Path(model_path).resolve()}",)
    return {"detector": ("observation.source=detector",), "pem": pem}


@dataclass(frozen=True, kw_only=True)
class BrakingCheckConfig:
    """The closed-loop check: the braking campaign's ``scenarios`` on seeds 0..``seeds``-1, the
    reckless driver behind the safety filter, on the detector grid and on the PEM's (issue 75's
    thresholds; not paper values).

    ``overrides`` are ``--set`` paths applied to both (the observation the PEM is for)."""

    seeds: int = 100  # issue 75: >= 100 seeds
    scenarios: tuple[str, ...] = ("ditch",)
    driver: str = "reckless"
    max_stopped_before_delta: int = 2
    max_stop_margin_delta_m: float = 0.2
    overrides: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        require(
            type(self.seeds) is int and self.seeds >= 1,
            "braking_seeds",
            f"must be an int >= 1, got {self.seeds!r}",
        )
        require(self.max_stopped_before_delta >= 0, "max_stopped_before_delta", "must be >= 0")
        require(
            math.isfinite(self.max_stop_margin_delta_m) and self.max_stop_margin_delta_m >= 0,
            "max_stop_margin_delta_m",
            "must be >= 0",
        )

    def campaign(self, model_path: str | Path | None) -> dict[str, Any]:
        """The two :class:`~negobs_gym.eval.braking_campaign.BrakingCampaignConfig` s, by grid."""
        from negobs_gym.eval.braking_campaign import BrakingCampaignConfig

        base = BrakingCampaignConfig(
            seeds=self.seeds,
            scenarios=self.scenarios,
            drivers=(self.driver,),
            filters=(True,),
            overrides=self.overrides,
        )
        grids = grid_overrides(model_path)
        return {m: replace(base, overrides=(*self.overrides, *grids[m])) for m in MODES}


def compare_braking(summaries: dict[str, list[Any]], config: BrakingCheckConfig) -> PemCheckResult:
    """Each scenario's stopped-before count and median stop margin of the detector's and the PEM's
    campaign (:func:`~negobs_gym.eval.braking_campaign.summarize` of each), and the checks."""
    figures: dict[str, float] = {}
    counts_ok, margins_ok = True, True
    for scenario in config.scenarios:
        name = f"{scenario}/{config.driver}/filter"
        got = {m: next(s for s in summaries[m] if s.name == name) for m in MODES}
        for m, s in got.items():
            figures[f"braking_{scenario}_episodes_{m}"] = float(s.episodes)
            figures[f"braking_{scenario}_stopped_before_{m}"] = float(s.stopped_before)
            figures[f"braking_{scenario}_entries_{m}"] = float(s.entries)
            figures[f"braking_{scenario}_stop_margin_median_m_{m}"] = _median(s.stop_margins_m)
            figures[f"braking_{scenario}_first_veto_gap_median_m_{m}"] = _median(s.first_veto_gaps_m)
        stopped = got["pem"].stopped_before - got["detector"].stopped_before
        margin = _median(got["pem"].stop_margins_m) - _median(got["detector"].stop_margins_m)
        figures[f"braking_{scenario}_stopped_before_delta"] = float(stopped)
        figures[f"braking_{scenario}_stop_margin_median_delta_m"] = margin
        figures[f"braking_{scenario}_first_veto_gap_median_delta_m"] = (
            figures[f"braking_{scenario}_first_veto_gap_median_m_pem"]
            - figures[f"braking_{scenario}_first_veto_gap_median_m_detector"]
        )
        counts_ok &= abs(stopped) <= config.max_stopped_before_delta
        margins_ok &= bool(abs(margin) <= config.max_stop_margin_delta_m)  # NaN (no stop) fails
    checks = {"check_braking_stopped_before": bool(counts_ok), "check_braking_stop_margin": margins_ok}
    return PemCheckResult(figures, checks)


def _median(values: list[float]) -> float:
    return float(np.median(values)) if values else math.nan


def check_braking(
    model_path: str | Path | None,
    config: BrakingCheckConfig,
    out_dir: str | Path,
    options: RunOptions | None = None,
) -> PemCheckResult:
    """Run the braking campaign on the detector grid and on the PEM ``model_path`` (None: the
    shipped one of the run's positive channel) into ``out_dir``/``braking_detector`` and
    ``braking_pem`` (each resumable), compare (:func:`compare_braking`) and write
    ``braking_check.txt``."""
    from negobs_gym.eval.braking_campaign import run_braking_campaign

    out = Path(out_dir)
    summaries = {
        m: run_braking_campaign(
            campaign, out / f"braking_{m}", _mode_options(out / f"braking_{m}", m, model_path, options)
        ).summaries
        for m, campaign in config.campaign(model_path).items()
    }
    result = compare_braking(summaries, config)
    write_text_atomic(out / "braking_check.txt", "\n".join(result.lines()) + "\n")
    return result


@dataclass(frozen=True, kw_only=True)
class PolicyCheckConfig:
    """The closed loop on a policy: ``policy`` (a shipped name, a saved model or a scripted driver's
    name, e.g. the privileged ``track_planner``, which passes pits closely) on seeds
    ``first_seed``.. of ``env_id`` (None: the env and ``--set`` of the policy's record), once on
    the detector grid and once on the PEM's, behind the safety filter or not (issue 76's transfer
    gap; not a paper value).

    ``overrides`` are ``--set`` paths applied to both, after the record's."""

    policy: str
    seeds: int = 20
    first_seed: int = 1_000_000
    env_id: str | None = None
    filtered: bool = True
    overrides: tuple[str, ...] = ()
    max_goal_gap: float = 0.10  # issue 76: |PEM goal rate - detector goal rate| <= 10 points

    def __post_init__(self) -> None:
        require(
            type(self.seeds) is int and self.seeds >= 1,
            "policy_seeds",
            f"must be an int >= 1, got {self.seeds!r}",
        )
        require(
            math.isfinite(self.max_goal_gap) and 0 <= self.max_goal_gap <= 1,
            "max_goal_gap",
            "must lie in [0, 1]",
        )

    def campaigns(self, model_path: str | Path | None) -> dict[str, Any]:
        """The two :class:`~negobs_gym.eval.policy_campaign.PolicyCampaignConfig` s, by grid."""
        from negobs_gym.drivers.zoo import recorded_env
        from negobs_gym.eval.policy_campaign import PolicyCampaignConfig
        from negobs_gym.spec import combine_overrides

        env_id, recorded = self.env_id, ()
        if env_id is None:
            found = recorded_env(self.policy)
            require(
                found is not None,
                "policy",
                f"{self.policy!r} has no record of its env: give the env to run it on (--policy-env)",
            )
            env_id, recorded = found[0], tuple(found[1])
        grids = grid_overrides(model_path)
        return {
            m: PolicyCampaignConfig(
                model_path=self.policy,
                env_id=env_id,
                seeds=self.seeds,
                first_seed=self.first_seed,
                filters=(self.filtered,),
                overrides=tuple(combine_overrides(recorded, (*self.overrides, *grid))),
            )
            for m, grid in grids.items()
        }


def compare_policy(summaries: dict[str, dict[str, Any]], config: PolicyCheckConfig) -> PemCheckResult:
    """The policy's outcomes on both grids (each :func:`~negobs_gym.eval.policy_campaign.summarize`)
    and the transfer-gap check."""
    label = "filter" if config.filtered else "nofilter"
    figures: dict[str, float] = {}
    for m in MODES:
        s = summaries[m][label]
        figures[f"policy_episodes_{m}"] = float(s["episodes"])
        for name in (
            "goals", "entries", "collisions", "left_track", "stopped", "vetoes_per_km", "false_vetoes_per_km",
            "mean_progress_m",
        ):  # fmt: skip
            figures[f"policy_{name}_{m}"] = float(s[name])
    gap = (figures["policy_goals_pem"] - figures["policy_goals_detector"]) / config.seeds
    figures["policy_goal_rate_gap"] = gap
    return PemCheckResult(figures, {"check_policy_goal_gap": bool(abs(gap) <= config.max_goal_gap)})


def check_policy(
    model_path: str | Path | None,
    config: PolicyCheckConfig,
    out_dir: str | Path,
    options: RunOptions | None = None,
) -> PemCheckResult:
    """Run the policy campaign on the detector grid and on the PEM ``model_path`` (None: the
    shipped one of the run's positive channel) into ``out_dir``/``policy_detector`` and
    ``policy_pem`` (each resumable), compare (:func:`compare_policy`) and write
    ``policy_check.txt``."""
    from negobs_gym.eval.policy_campaign import run_policy_campaign

    out = Path(out_dir)
    summaries = {
        m: run_policy_campaign(
            campaign, out / f"policy_{m}", _mode_options(out / f"policy_{m}", m, model_path, options)
        )[2]
        for m, campaign in config.campaigns(model_path).items()
    }
    result = compare_policy(summaries, config)
    write_text_atomic(out / "policy_check.txt", "\n".join(result.lines()) + "\n")
    return result
