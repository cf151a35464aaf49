"""Random structured scans through both extractors and the full detector: no crash, sane output."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector import NegativeObstacleDetector
from negobs_gym.detector.config import Hdl32FeatureConfig, Hdl64FeatureConfig
from negobs_gym.detector.hdl32 import extract_hdl32_pairs
from negobs_gym.detector.hdl64 import extract_hdl64_pairs
from negobs_gym.detector.synthetic import hdl32_side_rotation


@st.composite
def scans(draw):
    n_l = draw(st.integers(0, 8))
    n_c = draw(st.integers(0, 40))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["uniform", "plane", "spiky"]))
    if kind == "uniform":
        ranges = rng.uniform(0.0, 60.0, (n_l, n_c))
    elif kind == "plane":
        ranges = np.broadcast_to(np.linspace(3, 30, n_l)[:, None], (n_l, n_c)).copy()
    else:
        ranges = rng.choice([0.0, 1.0, 5.0, 1e4], size=(n_l, n_c))
    ranges[rng.random((n_l, n_c)) < draw(st.floats(0, 1))] = np.nan
    az = np.sort(rng.uniform(-np.pi, np.pi, n_c))
    az = az + np.arange(n_c) * 1e-6  # strictly increasing
    el = np.sort(rng.uniform(-0.6, 0.3, n_l))
    side = draw(st.booleans())
    rot = hdl32_side_rotation("left") if side else np.eye(3)
    h = draw(st.floats(0.3, 3.0))
    return StructuredScan("fuzz", ranges, az, el, rotation=rot, translation_m=[0.0, 0.0, h])


@settings(max_examples=60, deadline=None)
@given(scans())
def test_extractors_never_crash(scan):
    for fp in (
        extract_hdl64_pairs(scan, Hdl64FeatureConfig()),
        extract_hdl32_pairs(scan, Hdl32FeatureConfig()),
    ):
        assert fp.a_m.shape == fp.b_m.shape == fp.c_m.shape == (len(fp), 3)
        assert np.isfinite(fp.a_m).all() and np.isfinite(fp.b_m).all()


@st.composite
def poses(draw):
    values = draw(st.lists(st.floats(-50.0, 50.0, allow_nan=False), min_size=6, max_size=6))
    x, y, z, roll, pitch, yaw = values
    return Pose(x=x, y=y, z=z, roll=roll / 200.0, pitch=pitch / 200.0, yaw=yaw / 10.0)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(scans(), scans(), poses()), min_size=1, max_size=3))
def test_negative_detector_never_crashes(frames):
    detector = NegativeObstacleDetector()
    for top, side, pose in frames:
        detection = detector.update({"hdl64": top, "hdl32_left": side}, pose)
        assert detection.grid.shape == detection.grid_spec.shape and detection.grid.dtype == bool
        assert len(detection.pairs) <= detector.config.fusion.max_pairs
        assert all(np.isfinite(ob.outline_xy_m).all() for ob in detection.obstacles)
