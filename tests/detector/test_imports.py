"""The detector subpackage runs on recorded scans: it imports no simulator and no gymnasium."""

from __future__ import annotations

import subprocess
import sys


def test_detector_imports_no_simulator_or_gym() -> None:
    code = (
        "import sys, negobs_gym.detector as d\n"
        "d.NegativeObstacleDetector(); d.TraversableRegionDetector()\n"
        "bad = ('pybullet', 'gymnasium', 'matplotlib', 'negobs_gym.sim', 'negobs_gym.sensors',"
        " 'negobs_gym.envs')\n"
        "print([m for m in bad if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
