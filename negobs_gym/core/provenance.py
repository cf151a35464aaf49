"""Where a result came from: the code version and the machine, recorded beside benchmark figures,
training records and campaign summaries."""

from __future__ import annotations

import os
import platform
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from negobs_gym import __version__

__all__ = ["code_version", "machine"]


def code_version() -> str:
    """The package version, with ``git describe --always --dirty`` when it runs from a checkout."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists() or not (root / "pyproject.toml").is_file():
        return __version__
    try:
        done = subprocess.run(
            ["git", "describe", "--always", "--dirty"], cwd=root, capture_output=True, text=True, timeout=30
        )
    except (OSError, subprocess.TimeoutExpired):
        return __version__
    described = done.stdout.strip()
    return f"{__version__}+{described}" if done.returncode == 0 and described else __version__


def machine() -> dict[str, Any]:
    """What the figures were measured on: CPU model, cores this process may use, Python, numpy,
    platform, and the system's 5-minute load average now (the machine may be shared)."""
    model = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo") as info:
            model = next(
                (line.split(":", 1)[1].strip() for line in info if line.startswith("model name")), model
            )
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": model,
        "cores": cores,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "platform": platform.platform(),
        # the runnable processes over the last 5 minutes: above `cores`, others shared the CPUs
        "load_average": round(os.getloadavg()[1], 2) if hasattr(os, "getloadavg") else None,
    }
