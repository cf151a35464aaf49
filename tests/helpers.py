"""Helpers shared across the test packages."""

from __future__ import annotations

import os

HAS_PROC_STATM = os.path.exists("/proc/self/statm")


def rss_mb() -> float:
    """Resident set size of this process [MB] (Linux /proc)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
