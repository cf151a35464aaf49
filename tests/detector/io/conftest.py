"""Real recordings (tests/data/real, see its README) and clouds taken from them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REAL = Path(__file__).resolve().parents[2] / "data" / "real"
HDL32E_A = REAL / "hdl32e_a.pcap"
HDL32E_B = REAL / "hdl32e_b.pcap"
VLP32C_PCD = REAL / "vlp32c_nebula.pcd"


@pytest.fixture(scope="session")
def hdl32e_points() -> np.ndarray:
    """The real HDL-32E frame of hdl32e_b.pcap as decoded (ROS frame; x, y, z, intensity, ring)."""
    vd = pytest.importorskip("velodyne_decoder")
    ((_, points),) = list(vd.read_pcap(str(HDL32E_B), vd.Config(), as_pcl_structs=True))
    return points
