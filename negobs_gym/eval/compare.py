"""Two campaigns, or two groups of one, compared episode against episode on the seeds both ran.

A side is a ``negobs eval policy``, ``negobs eval braking`` or ``negobs scenario run`` output
folder and one group of its episodes: a filter setting of a policy campaign (``nofilter``,
``filter``, ``filter_positive``), a driver and filter of a braking campaign or a scenario run
(``reckless/filter``). Episodes pair by seed (policy) or by scenario and seed (braking, scenario):
within one env's terrain settings a seed is one course, so the two sides met the same ground.
Each outcome is tested with the exact McNemar test, each measure with the Wilcoxon signed-rank
test (:mod:`negobs_gym.eval.stats`); the rates carry their Wilson intervals.

Two ``negobs eval detection`` campaigns pair by course instead: their rows are obstacle-frames,
correlated within a course, so the Fig. 16 recall difference per distance bin gets an interval
from resampling the common courses together rather than a frame-level test. Reads the CSVs only:
no simulator is imported.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from negobs_gym.core.files import write_text_atomic
from negobs_gym.errors import require
from negobs_gym.eval.campaign import read_csv
from negobs_gym.eval.detection import DetectionEvalConfig
from negobs_gym.eval.detection_campaign import SENSOR_MODES, fig16_counts_by_course
from negobs_gym.eval.stats import (
    CONFIDENCE,
    PairedRate,
    PairedShift,
    format_interval,
    interval_list,
    nan_to_none,
    paired_rate,
    paired_shift,
    rate_interval,
    seed_bootstrap_difference,
)
from negobs_gym.eval.tables import bin_labels, key_value_table

__all__ = [
    "CampaignSide",
    "Comparison",
    "DetectionComparison",
    "compare_campaigns",
    "compare_detection_campaigns",
    "is_detection_folder",
    "load_side",
    "load_sides",
    "split_side",
    "write_comparison",
]

Row = Mapping[str, str]


@dataclass(frozen=True)
class _Outcome:
    name: str
    value: Callable[[Row], bool]
    applies: Callable[[Row], bool] = lambda row: True  # which pairs it is judged on


@dataclass(frozen=True)
class _Kind:
    """What a campaign's episode table holds and how its episodes pair and group."""

    table: str
    key: Callable[[Row], tuple[str, ...]]
    group: Callable[[Row], str]
    context: str  # the column that names what was driven (env id, scenario)
    outcomes: tuple[_Outcome, ...]
    measures: tuple[str, ...]
    reads: tuple[str, ...]  # every column the above read: a table without them is refused


def _flag(column: str) -> Callable[[Row], bool]:
    return lambda row: row[column] == "1"


def _flags(*columns: str) -> tuple[_Outcome, ...]:
    """Outcomes read straight from 0/1 columns, judged on every pair."""
    return tuple(_Outcome(column, _flag(column)) for column in columns)


def _per_scenario(
    table: str, outcomes: tuple[_Outcome, ...], measures: tuple[str, ...], reads: tuple[str, ...]
) -> _Kind:
    """A table of scenario episodes: paired by scenario and seed, grouped by driver and filter."""
    return _Kind(
        table=table,
        key=lambda row: (row["scenario"], row["seed"]),
        group=lambda row: f"{row['driver']}/{row['filter']}",
        context="scenario",
        outcomes=outcomes,
        measures=measures,
        reads=("scenario", "seed", "driver", "filter", *measures, *reads),
    )


def _obstacle(row: Row) -> bool:
    """A braking episode with an obstacle ahead: the obstacle-free track's gap is infinite."""
    return math.isfinite(float(row["start_gap_m"]))


POLICY_OUTCOMES = ("success", "goal", "entered", "collision", "left_track")
POLICY_MEASURES = ("progress_m", "distance_m", "veto_events")
SCENARIO_OUTCOMES = ("passed", "task_done", "entered", "stopped_before", "collision", "goal")

KINDS = {
    "policy": _Kind(
        table="policy",
        key=lambda row: (row["seed"],),
        group=lambda row: row["filter"],
        context="env",
        outcomes=_flags(*POLICY_OUTCOMES),
        measures=POLICY_MEASURES,
        reads=("seed", "filter", "env", *POLICY_OUTCOMES, *POLICY_MEASURES),
    ),
    "braking": _per_scenario(
        "braking",
        (
            _Outcome("stopped_before", lambda r: r["stopped"] == "1" and r["entered"] != "1", _obstacle),
            _Outcome("entered", _flag("entered"), _obstacle),
            _Outcome("collision", _flag("collision")),
            _Outcome("vetoed_free_track", lambda r: int(r["vetoes"]) > 0, lambda r: not _obstacle(r)),
        ),
        ("final_gap_m", "first_veto_gap_m", "veto_events"),
        ("stopped", "entered", "collision", "vetoes", "start_gap_m"),
    ),
    "scenario": _per_scenario(
        "results",
        _flags(*SCENARIO_OUTCOMES),
        ("stop_margin_m", "max_decel_mps2", "veto_events"),
        SCENARIO_OUTCOMES,
    ),
}


@dataclass(frozen=True)
class CampaignSide:
    """One group of one campaign's episodes, by pair key."""

    folder: Path
    kind: str  # "policy", "braking" or "scenario"
    group: str
    rows: dict[tuple[str, ...], dict[str, str]]
    driven: tuple[str, ...]  # the env ids (policy) or scenarios (braking) its episodes ran

    @property
    def label(self) -> str:
        return f"{self.folder}:{self.group}"


def split_side(text: str) -> tuple[Path, str | None]:
    """``DIR`` or ``DIR:GROUP`` (a folder whose own name has a colon is taken whole)."""
    if Path(text).is_dir() or ":" not in text:
        return Path(text), None
    folder, group = text.rsplit(":", 1)
    return Path(folder), group or None


def _groups(folder: Path) -> tuple[str, dict[str, list[dict[str, str]]]]:
    """The campaign kind of ``folder`` and its episode rows by group, in the table's order."""
    found = [name for name, kind in KINDS.items() if (folder / f"{kind.table}.csv").is_file()]
    require(
        len(found) == 1,
        "campaign_dir",
        f"no policy.csv, braking.csv or results.csv in {folder}: not a `negobs eval policy|braking "
        "--out` or `negobs scenario run --out` folder",
    )
    kind = KINDS[found[0]]
    table = folder / f"{kind.table}.csv"
    rows = read_csv(table)
    missing = [c for c in kind.reads if rows and c not in rows[0]]
    require(not missing, "campaign_dir", f"{table} lacks the columns {missing}: written by an older version")
    groups: dict[str, list[dict[str, str]]] = {}
    for row in rows:
        groups.setdefault(kind.group(row), []).append(row)
    return found[0], groups


def load_side(folder: str | Path, group: str | None = None) -> CampaignSide:
    """One group of a campaign folder; ``group`` may be left out where the folder has only one.

    Raises:
        ConfigError: not a policy, braking or scenario folder (field ``campaign_dir``), or the group
            is missing, unknown or ambiguous (field ``group``, naming the folder's groups).
    """
    folder = Path(folder)
    name, groups = _groups(folder)
    if group is None:
        require(
            len(groups) == 1,
            "group",
            f"{folder} holds the groups {sorted(groups)}: name one as {folder}:GROUP",
        )
        group = next(iter(groups))
    require(group in groups, "group", f"{folder} has no group {group!r}; it holds {sorted(groups)}")
    kind = KINDS[name]
    rows = {kind.key(r): r for r in groups[group]}
    driven = tuple(dict.fromkeys(r[kind.context] for r in groups[group]))
    return CampaignSide(folder, name, group, rows, driven)


def load_sides(a: str, b: str | None = None) -> tuple[CampaignSide, CampaignSide]:
    """The two sides from ``DIR[:GROUP]`` texts; without ``b``, the two groups of ``a``'s folder
    (a policy campaign run with ``--filter both``: ``nofilter`` against ``filter``), ``a``'s group
    first where it names one.

    Raises:
        ConfigError: as :func:`load_side`; without ``b``, a folder that does not hold exactly two
            groups (field ``b``).
    """
    folder, group = split_side(a)
    if b is not None:
        return load_side(folder, group), load_side(*split_side(b))
    _, groups = _groups(folder)
    require(
        len(groups) == 2,
        "b",
        f"{folder} holds the groups {sorted(groups)}: name both sides, e.g. {folder}:GROUP {folder}:GROUP",
    )
    first, second = groups
    if group == second:
        first, second = second, first
    return load_side(folder, group or first), load_side(folder, second)


@dataclass(frozen=True)
class Comparison:
    """The outcomes and measures of two sides on their common episodes."""

    a: CampaignSide
    b: CampaignSide
    pairs: int
    only_a: int  # episodes of A whose seed B did not run
    only_b: int
    rates: tuple[PairedRate, ...]
    shifts: tuple[PairedShift, ...]

    def as_dict(self) -> dict[str, Any]:
        """Plain data: both sides, the counts, every test with A's and B's intervals."""

        def side(s: CampaignSide) -> dict[str, Any]:
            return {"folder": str(s.folder), "kind": s.kind, "group": s.group, "driven": list(s.driven)}

        rates = [
            {
                **dataclasses.asdict(r),
                "difference": r.difference,
                "a_interval": rate_interval(r.a, r.pairs),
                "b_interval": rate_interval(r.b, r.pairs),
            }
            for r in self.rates
        ]
        return {
            "a": side(self.a),
            "b": side(self.b),
            "pairs": self.pairs,
            "only_a": self.only_a,
            "only_b": self.only_b,
            "confidence": CONFIDENCE,
            "outcomes": rates,
            "measures": [dataclasses.asdict(s) for s in self.shifts],
        }

    def markdown(self) -> str:
        """Two tables, outcomes and measures, under a line naming the sides and the pairs."""

        def side(s: CampaignSide) -> str:
            return f"{s.label} ({', '.join(s.driven)})"

        head = f"A = {side(self.a)}, B = {side(self.b)}: {self.pairs} episodes paired by seed"
        if self.only_a or self.only_b:
            head += f"; left out, their seed on one side only: {self.only_a} of A, {self.only_b} of B"
        rates = key_value_table(RATE_HEADER, [_rate_row(r) for r in self.rates])
        shifts = key_value_table(SHIFT_HEADER, [_shift_row(s) for s in self.shifts])
        return f"{head}\n\n{rates}\n\n{shifts}\n"


_INTERVAL = f"{CONFIDENCE:.0%} interval"
RATE_HEADER = (
    "outcome",
    "episodes",
    f"A ({_INTERVAL})",
    f"B ({_INTERVAL})",
    "A only",
    "B only",
    "A - B",
    "p (exact McNemar)",
)
SHIFT_HEADER = ("measure", "episodes", "A median", "B median", "median of A - B", "p (Wilcoxon signed-rank)")


def _rate_row(r: PairedRate) -> tuple[object, ...]:
    a, b = (f"{k} ({format_interval(rate_interval(k, r.pairs))})" for k in (r.a, r.b))
    return r.name, r.pairs, a, b, r.a_only, r.b_only, f"{r.difference:+.2f}", f"{r.p_value:.3g}"


def _shift_row(s: PairedShift) -> tuple[object, ...]:
    medians = (f"{v:.2f}" for v in (s.median_a, s.median_b))
    return s.name, s.pairs, *medians, f"{s.median_difference:+.2f}", f"{s.p_value:.3g}"


def compare_campaigns(a: CampaignSide, b: CampaignSide) -> Comparison:
    """Pair the two sides' episodes and test each outcome and measure of their kind; an outcome
    or measure that no pair has (stops on the obstacle-free track, a gap where no side vetoed) is
    left out.

    Raises:
        ConfigError: the sides are of different kinds (field ``b``), are the same group of the same
            folder, or share no seed (field ``pairs``).
    """
    require(a.kind == b.kind, "b", f"{a.label} is a {a.kind} campaign, {b.label} a {b.kind} one")
    require(
        (a.folder.resolve(), a.group) != (b.folder.resolve(), b.group),
        "b",
        f"{a.label} is compared with itself",
    )
    keys = [k for k in a.rows if k in b.rows]
    require(bool(keys), "pairs", f"{a.label} and {b.label} share no seed")
    kind = KINDS[a.kind]
    rates = []
    for outcome in kind.outcomes:
        judged = [k for k in keys if outcome.applies(a.rows[k])]
        if judged:
            rates.append(
                paired_rate(
                    outcome.name,
                    [outcome.value(a.rows[k]) for k in judged],
                    [outcome.value(b.rows[k]) for k in judged],
                )
            )
    shifts = []
    for measure in kind.measures:
        x = [float(a.rows[k][measure]) for k in keys]
        y = [float(b.rows[k][measure]) for k in keys]
        if any(math.isfinite(u) and math.isfinite(v) for u, v in zip(x, y, strict=True)):
            shifts.append(paired_shift(measure, x, y))
    return Comparison(
        a, b, len(keys), len(a.rows) - len(keys), len(b.rows) - len(keys), tuple(rates), tuple(shifts)
    )


@dataclass(frozen=True)
class DetectionComparison:
    """Two detection campaigns' Fig. 16 recall on their common courses, per mode and distance bin:
    each side's recall, and the difference A - B with its paired-bootstrap interval."""

    a: Path
    b: Path
    courses: int
    only_a: int  # courses of A that B did not drive
    only_b: int
    distance_bins: tuple[str, ...]
    modes: dict[str, dict[str, list[Any]]]  # mode -> recall_a, recall_b, difference, interval (each per bin)

    def as_dict(self) -> dict[str, Any]:
        """Plain data (None where a bin was seen by fewer than two courses)."""
        return {**dataclasses.asdict(self), "a": str(self.a), "b": str(self.b), "confidence": CONFIDENCE}

    def markdown(self) -> str:
        """One table per sensor mode under a line naming the campaigns and the courses."""
        head = f"A = {self.a}, B = {self.b}: Fig. 16 recall (25-34-cell pits), {self.courses} courses in both"
        if self.only_a or self.only_b:
            head += f"; left out, driven by one only: {self.only_a} of A, {self.only_b} of B"
        parts = [head]
        for mode, m in self.modes.items():
            rows = [_detection_row(d, m, j) for j, d in enumerate(self.distance_bins)]
            header = [
                "distance",
                "A recall",
                "B recall",
                "A - B",
                f"{_INTERVAL} of A - B (courses resampled)",
            ]
            parts += [f"## {mode}", key_value_table(header, rows)]
        return "\n\n".join(parts) + "\n"


def _detection_row(distance: str, m: dict[str, list[Any]], j: int) -> tuple[str, ...]:
    recalls = (_value(m["recall_a"][j]), _value(m["recall_b"][j]))
    return distance, *recalls, _value(m["difference"][j], "+.3f"), format_interval(m["interval"][j])


def _value(v: float | None, spec: str = ".3f") -> str:
    return "-" if v is None else format(v, spec)


def is_detection_folder(folder: str | Path) -> bool:
    """Whether ``folder`` holds a ``negobs eval detection --out`` campaign."""
    return (Path(folder) / "obstacles.csv").is_file() and (Path(folder) / "frames.csv").is_file()


def compare_detection_campaigns(a: str | Path, b: str | Path) -> DetectionComparison:
    """Pair two detection campaigns by course (seed) and give, per sensor mode and distance bin,
    each Fig. 16 recall and the difference with its interval from resampling the common courses
    together (:func:`~negobs_gym.eval.stats.seed_bootstrap_difference`). A seed is the same course
    only with the same frames, so a seed driven for different frame counts is refused. The
    distance bins are :class:`~negobs_gym.eval.DetectionEvalConfig`'s defaults (paper N Table 7),
    applied to each row's recorded distance; the recall flags are each campaign's own.

    Raises:
        ConfigError: a folder that is no detection campaign (field ``campaign_dir``), no common
            course or fewer than two (``pairs``), or a course driven for different frame counts.
    """
    folders = Path(a), Path(b)
    for folder in folders:
        require(
            is_detection_folder(folder),
            "campaign_dir",
            f"no obstacles.csv and frames.csv in {folder}: not a `negobs eval detection --out` folder",
        )
    require(folders[0].resolve() != folders[1].resolve(), "b", f"{a} is compared with itself")
    frames = [_frames_by_seed(folder) for folder in folders]
    common = sorted(set(frames[0]) & set(frames[1]))
    require(
        len(common) >= 2, "pairs", f"{a} and {b} have {len(common)} course(s) in common; resampling needs two"
    )
    differ = [seed for seed in common if frames[0][seed] != frames[1][seed]]
    require(
        not differ,
        "pairs",
        f"courses {differ[:5]} ran {[frames[0][s] for s in differ[:5]]} frames in {a} and "
        f"{[frames[1][s] for s in differ[:5]]} in {b}: a seed is one course only at one frame count",
    )
    config = DetectionEvalConfig()
    on_common = [fig16_counts_by_course(folder / "obstacles.csv", config).on(common) for folder in folders]
    modes = {}
    for mode in SENSOR_MODES:
        sides = [(c.recalled[mode], c.seen) for c in on_common]
        difference, low, high = seed_bootstrap_difference(*sides)
        modes[mode] = {
            "recall_a": nan_to_none(on_common[0].recall(mode)),
            "recall_b": nan_to_none(on_common[1].recall(mode)),
            "difference": nan_to_none(difference),
            "interval": interval_list(low, high),
        }
    return DetectionComparison(
        folders[0],
        folders[1],
        len(common),
        len(frames[0]) - len(common),
        len(frames[1]) - len(common),
        tuple(bin_labels(config.distance_bin_edges_m, " m")),
        modes,
    )


def _frames_by_seed(folder: Path) -> dict[int, int]:
    frames: dict[int, int] = {}
    for row in read_csv(folder / "frames.csv"):
        frames[int(row["seed"])] = frames.get(int(row["seed"]), 0) + 1
    return frames


def write_comparison(comparison: Comparison | DetectionComparison, out_dir: str | Path) -> tuple[Path, Path]:
    """``compare.md`` and ``compare.json`` in ``out_dir``, each written atomically."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    markdown = write_text_atomic(out / "compare.md", comparison.markdown())
    return markdown, write_text_atomic(
        out / "compare.json", json.dumps(comparison.as_dict(), indent=1, sort_keys=True)
    )
