"""Analytic LUX scans: geometry against closed forms, determinism, config checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.detector.traversable import Box, LuxRig, TrackScene, synthetic_scan
from negobs_gym.errors import ConfigError


def test_flat_ground_ranges_match_closed_form() -> None:
    rig = LuxRig()
    scan = synthetic_scan(TrackScene(left_half_width_m=30.0, right_half_width_m=30.0), rig)
    assert scan.shape == (4, 441)
    centre = scan.shape[1] // 2  # azimuth 0
    for n, e in enumerate(rig.elevations_deg):
        depression = math.radians(rig.pitch_down_deg - e)
        assert scan.ranges_m[n, centre] == pytest.approx(rig.height_m / math.sin(depression), abs=1e-3)
    assert np.allclose(scan.points_vehicle[..., 2], 0.0, atol=1e-3)


def test_box_face_and_drop_off() -> None:
    box = Box(x_m=0.0, y_m=11.0, size_x_m=2.0, size_y_m=2.0, height_m=1.5)
    scan = synthetic_scan(TrackScene(boxes=(box,)))
    centre = scan.shape[1] // 2
    assert scan.points_vehicle[1:, centre, 1] == pytest.approx(10.0, abs=1e-6)
    drop = synthetic_scan(TrackScene(border="drop", left_half_width_m=2.0, right_half_width_m=2.0))
    z = drop.points_vehicle[..., 2]
    assert np.nanmin(z) == pytest.approx(-3.0, abs=1e-3)


def test_noise_is_deterministic_and_needs_rng() -> None:
    a = synthetic_scan(TrackScene(), range_noise_m=0.02, rng=np.random.default_rng(5))
    b = synthetic_scan(TrackScene(), range_noise_m=0.02, rng=np.random.default_rng(5))
    assert np.array_equal(a.ranges_m, b.ranges_m, equal_nan=True)
    with pytest.raises(ValueError, match="rng"):
        synthetic_scan(TrackScene(), range_noise_m=0.02)


def test_invalid_scene_names_field() -> None:
    with pytest.raises(ConfigError, match="bend_radius_m"):
        TrackScene(bend_radius_m=0.5)
    with pytest.raises(ConfigError, match="border"):
        TrackScene(border="cliff")  # type: ignore[arg-type]


def test_bumps_are_seeded_and_move_with_travel() -> None:
    from negobs_gym.detector.traversable import random_bumps

    a = random_bumps(np.random.default_rng(1), amplitude_m=0.02, wavelength_m=1.5)
    assert a == random_bumps(np.random.default_rng(1), amplitude_m=0.02, wavelength_m=1.5)
    scene = TrackScene(bumps=a)
    x, y = np.meshgrid(np.linspace(-3, 3, 61), np.linspace(5, 15, 101))
    h = scene.height(x, y)
    assert 0.01 < h.std() < 0.04
    moved = TrackScene(bumps=a, travelled_m=2.0)
    assert np.allclose(moved.height(x, y), scene.height(x, y + 2.0))
