"""The paper T detector imports numpy/scipy/scikit-learn only (SPEC §1.2)."""

from __future__ import annotations

import subprocess
import sys


def test_no_simulator_or_gym_import() -> None:
    code = (
        "import sys, negobs_gym.detector.traversable as t\n"
        "bad = [m for m in ('pybullet', 'gymnasium', 'negobs_gym.sim', 'negobs_gym.sensors', 'matplotlib')"
        " if m in sys.modules]\n"
        "print(bad)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
