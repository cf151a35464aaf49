"""Tests of the terrain generator: determinism, roughness statistics, borders, config errors."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.sim.carving import NegativeObstacleSpec
from negobs_gym.sim.terrain import (
    BendSpec,
    BorderConfig,
    RoughnessConfig,
    TerrainConfig,
    build_centreline,
    generate_terrain,
    track_coordinates,
)
from negobs_gym.sim.types import PositiveObstacle, Track

SMALL = dict(length_m=30.0, corridor_width_m=20.0, lead_in_m=5.0, run_out_m=5.0)


def _lateral_grid(terrain):
    hf = terrain.heightfield
    ny, nx = hf.shape
    xs = hf.origin_m[0] + hf.resolution_m * np.arange(nx)
    ys = hf.origin_m[1] + hf.resolution_m * np.arange(ny)
    return track_coordinates(terrain.track, np.stack(np.meshgrid(xs, ys), axis=-1))


def test_same_seed_same_bytes_and_different_seed_differs() -> None:
    config = TerrainConfig(**SMALL, bends=(BendSpec(start_m=5.0, length_m=20.0, angle_deg=30.0),))
    a = generate_terrain(config, 7)
    b = generate_terrain(config, 7)
    c = generate_terrain(config, 8)
    assert a.heightfield.heights_m.dtype == np.float32
    assert a.heightfield.heights_m.tobytes() == b.heightfield.heights_m.tobytes()
    assert a.heightfield.heights_m.shape == c.heightfield.heights_m.shape
    assert np.mean(np.abs(a.heightfield.heights_m - c.heightfield.heights_m)) > 0.01


def test_flat_config_gives_flat_ground() -> None:
    terrain = generate_terrain(TerrainConfig(**SMALL, roughness=RoughnessConfig.flat()), 3)
    assert np.all(terrain.heightfield.heights_m == 0.0)


def test_roughness_amplitudes_within_config() -> None:
    rough = RoughnessConfig(slope_amplitude_m=0.0, rut_depth_m=0.0)
    terrain = generate_terrain(TerrainConfig(**SMALL, roughness=rough), 1)
    _, lateral = _lateral_grid(terrain)
    h = terrain.heightfield.heights_m
    peak = rough.bump_amplitude_m + rough.fine_amplitude_m
    on_track = np.abs(lateral) <= 0.5 * 6.0 - 0.05
    off_track = np.abs(lateral) >= 0.5 * 6.0 + rough.track_blend_m + 0.05
    assert np.max(np.abs(h[on_track])) <= rough.track_scale * peak + 1e-6
    assert np.max(np.abs(h[off_track])) <= peak + 1e-6
    # Bumps really are there off the track, and much smaller on it.
    assert np.max(np.abs(h[off_track])) >= 0.5 * rough.bump_amplitude_m
    assert np.std(h[on_track]) < 0.3 * np.std(h[off_track])


def test_ruts_follow_the_track() -> None:
    rough = RoughnessConfig(
        slope_amplitude_m=0.0,
        bump_amplitude_m=0.0,
        fine_amplitude_m=0.0,
        rut_depth_m=0.05,
        rut_spacing_m=1.8,
    )
    terrain = generate_terrain(TerrainConfig(**SMALL, roughness=rough), 0)
    z_rut = terrain.heightfield.height_at(np.array([[0.9, 10.0], [-0.9, 20.0]]))
    z_mid = terrain.heightfield.height_at(np.array([[0.0, 10.0], [3.0, 10.0]]))
    np.testing.assert_allclose(z_rut, -0.05, atol=2e-3)
    assert np.all(np.abs(z_mid) < 0.01)


def test_bank_and_dropoff_profiles() -> None:
    config = TerrainConfig(
        **SMALL,
        roughness=RoughnessConfig.flat(),
        left_border=BorderConfig(kind="bank", bank_height_m=0.8),
        right_border=BorderConfig(kind="dropoff", dropoff_depth_m=1.5),
    )
    terrain = generate_terrain(config, 0)
    assert terrain.track.border_kinds == ("bank", "dropoff")
    # Left of +Y is -X. Track half-width 3 m, verge 1.5 m, bank run 2 m, drop run 0.5 m.
    z = terrain.heightfield.height_at(np.array([[-4.0, 10.0], [-7.0, 10.0], [4.0, 10.0], [6.0, 10.0]]))
    np.testing.assert_allclose(z, [0.0, 0.8, 0.0, -1.5], atol=1e-5)
    faces = terrain.metadata["border_faces_xy_m"]
    assert set(faces) == {"left", "right"}
    np.testing.assert_allclose(faces["left"][:, 0], -4.5)
    np.testing.assert_allclose(faces["right"][:, 0], 4.5)


def test_centreline_bend_heading_and_length() -> None:
    config = TerrainConfig(length_m=60.0, bends=(BendSpec(start_m=10.0, length_m=31.4159, angle_deg=90.0),))
    line = build_centreline(config)
    seg = np.linalg.norm(np.diff(line, axis=0), axis=1)
    assert seg.sum() == pytest.approx(60.0, abs=1e-6)
    # After a 90 deg left bend the track runs along world -X.
    end_dir = line[-1] - line[-2]
    np.testing.assert_allclose(end_dir / np.linalg.norm(end_dir), [-1.0, 0.0], atol=1e-6)
    # Radius 20 m: the bend ends 20 m left and 10 + 20 m ahead of the start.
    end_of_bend = line[round(41.4159 / 0.1)]
    np.testing.assert_allclose(end_of_bend, [-20.0, 30.0], atol=0.05)


def test_track_pose_and_coordinates_round_trip() -> None:
    config = TerrainConfig(**SMALL, bends=(BendSpec(start_m=5.0, length_m=20.0, angle_deg=40.0),))
    terrain = generate_terrain(config, 0)
    stations = np.array([0.0, 7.0, 15.0, 28.0])
    laterals = np.array([0.0, 2.0, -3.0, 1.0])
    xy, yaw = terrain.track.pose_at(stations, laterals)
    assert yaw[0] == pytest.approx(0.0)
    s_back, l_back = track_coordinates(terrain.track, xy)
    np.testing.assert_allclose(s_back, stations, atol=0.02)
    np.testing.assert_allclose(l_back, laterals, atol=0.01)
    # Lateral + is to the right: at the start (facing +Y) that is world +X.
    right, _ = terrain.track.pose_at(0.0, 1.0)
    np.testing.assert_allclose(right, [1.0, 0.0], atol=1e-9)


def test_corridor_size_and_start_goal() -> None:
    terrain = generate_terrain(TerrainConfig(length_m=50.0, corridor_width_m=30.0), 0)
    x0, x1, y0, y1 = terrain.heightfield.extent_m
    assert x1 - x0 == pytest.approx(30.0, abs=0.25)
    assert y1 - y0 == pytest.approx(50.0 + 20.0, abs=0.25)
    assert terrain.start_xy_yaw == (0.0, 0.0, 0.0)
    assert terrain.goal_xy_m == pytest.approx((0.0, 45.0))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"resolution_m": 0.0}, "resolution_m"),
        ({"resolution_m": float("nan")}, "resolution_m"),
        ({"length_m": -1.0}, "length_m"),
        ({"track_width_m": 40.0}, "corridor_width_m"),
        ({"bends": (BendSpec(start_m=0.0, length_m=5.0, angle_deg=90.0),)}, "bends[0].length_m"),
        ({"bends": (BendSpec(start_m=190.0, length_m=50.0, angle_deg=10.0),)}, "bends[0].length_m"),
        ({"left_border": "bank"}, "left_border"),
        ({"negative_obstacles": [NegativeObstacleSpec(station_m=5.0)]}, "negative_obstacles"),
    ],
)
def test_bad_terrain_config_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        TerrainConfig(**kwargs)
    assert info.value.field == field


@pytest.mark.parametrize(
    ("factory", "field"),
    [
        (lambda: BorderConfig(kind="cliff"), "kind"),
        (lambda: BorderConfig(bank_height_m=-1.0), "bank_height_m"),
        (lambda: RoughnessConfig(bump_amplitude_m=-0.1), "bump_amplitude_m"),
        (lambda: RoughnessConfig(track_scale=1.5), "track_scale"),
        (lambda: BendSpec(start_m=0.0, length_m=0.0, angle_deg=10.0), "length_m"),
    ],
)
def test_bad_sub_configs_name_the_field(factory, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        factory()
    assert info.value.field == field


@pytest.mark.parametrize("seed", [-1, 1.5, "0", True])
def test_bad_seed(seed) -> None:
    with pytest.raises(ConfigError, match="seed"):
        generate_terrain(TerrainConfig(**SMALL), seed)


def test_configs_are_frozen() -> None:
    config = TerrainConfig()
    with pytest.raises(AttributeError):
        config.length_m = 5.0  # type: ignore[misc]


def test_config_must_be_a_terrain_config() -> None:
    with pytest.raises(ConfigError, match="config"):
        generate_terrain({"length_m": 10.0}, 0)  # type: ignore[arg-type]


def test_track_pose_extrapolates_straight_and_rejects_bad_centreline() -> None:
    track = Track(centreline_xy_m=np.array([[0.0, 0.0], [0.0, 10.0], [10.0, 10.0]]), width_m=4.0)
    assert track.length_m == pytest.approx(20.0)
    xy, yaw = track.pose_at(np.array([-5.0, 25.0]))
    np.testing.assert_allclose(xy, [[0.0, -5.0], [15.0, 10.0]])
    np.testing.assert_allclose(yaw, [0.0, -np.pi / 2])  # yaw -90 deg faces world +X
    with pytest.raises(GeometryError, match="centreline_xy_m"):
        Track(centreline_xy_m=np.zeros((1, 2)), width_m=4.0).pose_at(0.0)


def test_positive_obstacle_footprint_follows_the_body_frame_and_yaw() -> None:
    box = PositiveObstacle("b", "box", "box", np.array([1.0, 2.0, 0.5]), np.array([0.5, 1.0, 0.5]), np.pi / 2)
    # body X (right) turned 90 deg left points along world +Y, body Y (forward) along world -X
    corners = box.footprint_xy_m
    np.testing.assert_allclose(corners.min(axis=0), [0.0, 1.5], atol=1e-12)
    np.testing.assert_allclose(corners.max(axis=0), [2.0, 2.5], atol=1e-12)
    pole = PositiveObstacle("p", "pole", "cylinder", np.array([0.0, 0.0, 1.0]), np.array([0.2, 0.2, 1.0]))
    np.testing.assert_allclose(np.hypot(*pole.footprint_xy_m.T), 0.2)
    assert pole.footprint_xy_m.shape == (16, 2)
