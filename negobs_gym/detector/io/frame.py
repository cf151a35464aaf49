"""One recorded frame with where it came from, and the errors every reader raises alike."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.loaders import RingSource
from negobs_gym.errors import ScanError

__all__ = ["RecordedFrame", "check_not_empty", "unreadable"]


@dataclass(frozen=True, eq=False)
class RecordedFrame:
    """A structured scan read from a recording.

    Attributes:
        scan: The frame as the detector reads it.
        source: File (or bag / pcap) it came from.
        index: Frame number within ``source``, from 0.
        ring_source: How each point's laser was found: ``"ring_field"``, ``"point_order"`` or
            ``"elevation_table"`` (see :mod:`negobs_gym.detector.loaders`).
        n_points: Points in the recorded cloud (before binning).
        frame_id: The cloud's coordinate frame where the recording names it (a bag message's
            ``header.frame_id``), else None.
        column_time_s: When each column of ``scan`` was fired, after the cloud's stamp [s]
            (:func:`~negobs_gym.detector.io.setup.column_time_offsets`), where it was read; None
            otherwise.
    """

    scan: StructuredScan
    source: str
    index: int
    ring_source: RingSource
    n_points: int
    frame_id: str | None = None
    column_time_s: np.ndarray | None = None


def unreadable(name: str, what: str, error: BaseException) -> ScanError:
    """One-line :class:`ScanError` for a file a third-party reader rejected (its message's first line)."""
    first = (str(error).strip().splitlines() or [""])[0]
    return ScanError(f"{name}: not a readable {what} ({type(error).__name__}: {first})")


def check_not_empty(name: str) -> None:
    """ScanError if ``name`` is an empty file (third-party readers give obscure messages for it)."""
    if os.path.isfile(name) and os.path.getsize(name) == 0:
        raise ScanError(f"{name}: file is empty")
