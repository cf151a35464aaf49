"""Paper N's Tables 6 and 7 (the reference values) and text tables of campaign results beside them."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np

# paper N Table 6: occurrences of marked areas per size bin (rows, cells 15-19 ... 45-55) and
# distance bin (columns, 6-8 ... 18-20 m)
PAPER_N_TABLE6: tuple[tuple[int, ...], ...] = (
    (86, 92, 89, 88, 68, 46, 45),
    (92, 189, 167, 155, 110, 95, 93),
    (101, 192, 187, 157, 123, 81, 75),
    (85, 184, 174, 163, 154, 89, 84),
    (94, 196, 157, 140, 131, 91, 83),
    (89, 184, 84, 80, 65, 53, 56),
    (83, 123, 89, 85, 71, 68, 64),
)
# paper N Table 7: recall of the fused detector, same layout
PAPER_N_TABLE7: tuple[tuple[float, ...], ...] = (
    (0.977, 0.891, 0.787, 0.693, 0.426, 0.217, 0.044),
    (0.957, 0.862, 0.79, 0.781, 0.482, 0.326, 0.118),
    (0.96, 0.922, 0.85, 0.72, 0.512, 0.284, 0.173),
    (0.941, 0.929, 0.839, 0.773, 0.571, 0.326, 0.167),
    (0.957, 0.918, 0.892, 0.8, 0.618, 0.429, 0.205),
    (0.955, 0.951, 0.905, 0.775, 0.646, 0.415, 0.179),
    (0.988, 0.943, 0.876, 0.824, 0.606, 0.456, 0.219),
)


def paper_n_fig16_fused() -> list[float]:
    """Paper N's fused recall of 25-34-cell areas per distance bin (Fig. 16's fused curve).

    Fig. 16 prints no numbers; its fused curve is the same detector on the same data as Table 7,
    so we take Table 7's rows 25-29 and 30-34 weighted by their Table 6 occurrences.
    """
    n = np.asarray(PAPER_N_TABLE6, dtype=float)[2:4]
    r = np.asarray(PAPER_N_TABLE7, dtype=float)[2:4]
    return [round(float(v), 3) for v in (n * r).sum(axis=0) / n.sum(axis=0)]


def bin_labels(edges: Sequence[float], unit: str = "") -> list[str]:
    """Row/column labels of half-open bins, e.g. ``15-19`` for cells, ``6-8 m`` for metres."""
    if unit:
        return [f"{lo:g}-{hi:g}{unit}" for lo, hi in itertools.pairwise(edges)]
    return [f"{int(lo)}-{int(hi) - 1}" for lo, hi in itertools.pairwise(edges)]


def _markdown(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def occurrence_table(
    occurrences: Sequence[Sequence[int]], size_bins: Sequence[str], distance_bins: Sequence[str]
) -> str:
    """Table 6 layout, markdown: ``ours (paper N)`` per size x distance bin."""
    rows = [
        [size] + [f"{int(ours)} ({paper})" for ours, paper in zip(row, PAPER_N_TABLE6[i], strict=True)]
        for i, (size, row) in enumerate(zip(size_bins, occurrences, strict=True))
    ]
    return _markdown(["cells \\ distance", *distance_bins], rows)


def recall_table(recall: np.ndarray, size_bins: Sequence[str], distance_bins: Sequence[str]) -> str:
    """Table 7 layout, markdown: ``ours (paper N)`` recall per bin, ``-`` where nothing was seen."""
    rows = []
    for i, size in enumerate(size_bins):
        cells = []
        for j, paper in enumerate(PAPER_N_TABLE7[i]):
            ours = float(recall[i][j])
            cells.append(f"{'-' if math.isnan(ours) else f'{ours:.3f}'} ({paper:.3f})")
        rows.append([size, *cells])
    return _markdown(["cells \\ distance", *distance_bins], rows)


def key_value_table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A small markdown table of already-computed values (floats with 3 decimals)."""
    text = [[f"{v:.3f}" if isinstance(v, float) else str(v) for v in row] for row in rows]
    return _markdown(header, text)
