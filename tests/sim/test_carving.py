"""Tests of negative-obstacle carving and positive-obstacle placement."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from negobs_gym.core.geometry import points_in_polygon
from negobs_gym.errors import ConfigError
from negobs_gym.sim.carving import (
    DEPTH_RANGE_M,
    MIN_NEGATIVE_WIDTH_M,
    PAPER_N_PIT_SIZES_M,
    NegativeObstacleSpec,
    PositiveObstacleSpec,
    carve_negative_obstacle,
    obstacle_outline,
    place_positive_obstacle,
    sample_pit_spec,
)
from negobs_gym.sim.terrain import RoughnessConfig, TerrainConfig, generate_terrain
from negobs_gym.sim.types import HeightField

RES = 0.1


def _field(seed: int = 0, rough: bool = True) -> HeightField:
    roughness = RoughnessConfig() if rough else RoughnessConfig.flat()
    config = TerrainConfig(length_m=20.0, corridor_width_m=16.0, roughness=roughness)
    return generate_terrain(config, seed).heightfield


def _sample_xy(hf: HeightField) -> np.ndarray:
    ny, nx = hf.shape
    xs = hf.origin_m[0] + hf.resolution_m * np.arange(nx)
    ys = hf.origin_m[1] + hf.resolution_m * np.arange(ny)
    return np.stack(np.meshgrid(xs, ys), axis=-1)


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


@pytest.mark.parametrize(("length_m", "width_m"), [(1.0, 0.5), (1.0, 0.8), (1.5, 0.6), (1.0, 1.0)])
def test_paper_pit_sizes_outline_floor_and_untouched_outside(length_m: float, width_m: float) -> None:
    hf = _field()
    spec = NegativeObstacleSpec(kind="pit", length_m=length_m, width_m=width_m, depth_m=0.8, xy_m=(0.33, 8.0))
    centre = np.array(spec.xy_m)
    new, rec = carve_negative_obstacle(hf, spec, centre_xy_m=centre, yaw_rad=0.0, obstacle_id="pit-0")
    assert rec.obstacle_id == "pit-0" and rec.kind == "pit"
    assert _signed_area(rec.outline_xy_m) == pytest.approx(length_m * width_m)
    lo, hi = rec.outline_xy_m.min(axis=0), rec.outline_xy_m.max(axis=0)
    np.testing.assert_allclose(hi - lo, [width_m, length_m])  # yaw 0: length along +Y
    np.testing.assert_allclose(rec.centre_xy_m, centre)
    # The rim is the mean pre-carve surface along the outline; floor = rim - depth.
    rim = float(np.mean(hf.height_at(rec.outline_xy_m)))
    assert rec.floor_z_m == pytest.approx(rim - 0.8, abs=0.02)
    xy = _sample_xy(hf)
    inside = np.all((xy >= lo - 1e-9) & (xy <= hi + 1e-9), axis=-1)
    assert inside.sum() > 0
    assert np.all(new.heights_m[inside] == np.float32(rec.floor_z_m))
    assert np.array_equal(new.heights_m[~inside], hf.heights_m[~inside])
    # A downward ray at the centre hits the floor at the recorded depth below the rim.
    assert float(new.height_at(centre[None])[0]) == pytest.approx(rec.floor_z_m, abs=0.02)
    # The input heightfield is not modified.
    assert not np.shares_memory(new.heights_m, hf.heights_m)


def test_rotated_trench_outline_is_ccw_and_carved() -> None:
    hf = _field(rough=False)
    spec = NegativeObstacleSpec(kind="trench", length_m=3.0, width_m=8.0, depth_m=1.2, xy_m=(0, 10))
    yaw = math.radians(30.0)
    new, rec = carve_negative_obstacle(
        hf, spec, centre_xy_m=np.array([0.0, 10.0]), yaw_rad=yaw, obstacle_id="t"
    )
    assert _signed_area(rec.outline_xy_m) == pytest.approx(24.0)
    assert rec.floor_z_m == pytest.approx(-1.2)
    assert new.heights_m.min() == pytest.approx(-1.2)
    # Carved area matches the rectangle's area to within the sample spacing.
    carved_area = np.count_nonzero(new.heights_m < -0.6) * RES * RES
    assert carved_area == pytest.approx(24.0, rel=0.05)
    # A point 1.0 m along the (rotated) length axis is inside, 1.7 m is outside.
    fwd = np.array([-math.sin(yaw), math.cos(yaw)])
    z = new.height_at(np.array([[0.0, 10.0] + 1.0 * fwd, [0.0, 10.0] + 1.7 * fwd]))
    assert z[0] == pytest.approx(-1.2) and z[1] == pytest.approx(0.0)


def test_crater_is_round() -> None:
    hf = _field(rough=False)
    spec = NegativeObstacleSpec(kind="crater", length_m=2.0, width_m=2.0, depth_m=0.5, xy_m=(1, 9))
    new, rec = carve_negative_obstacle(
        hf, spec, centre_xy_m=np.array([1.0, 9.0]), yaw_rad=0.0, obstacle_id="c"
    )
    radii = np.linalg.norm(rec.outline_xy_m - [1.0, 9.0], axis=1)
    np.testing.assert_allclose(radii, 1.0)
    assert _signed_area(rec.outline_xy_m) > 0
    carved_area = np.count_nonzero(new.heights_m < -0.25) * RES * RES
    assert carved_area == pytest.approx(math.pi, rel=0.08)
    assert new.height_at(np.array([[1.0, 9.0], [1.0, 10.15]])).tolist() == pytest.approx([-0.5, 0.0])


def test_sloped_walls_reach_the_floor_and_never_raise_ground() -> None:
    hf = _field()
    spec = NegativeObstacleSpec(
        kind="ditch", length_m=3.0, width_m=3.0, depth_m=0.6, wall_slope_deg=45.0, xy_m=(0, 8)
    )
    new, rec = carve_negative_obstacle(
        hf, spec, centre_xy_m=np.array([0.0, 8.0]), yaw_rad=0.0, obstacle_id="d"
    )
    assert np.all(new.heights_m <= hf.heights_m)
    assert float(new.height_at(np.array([[0.0, 8.0]]))[0]) == pytest.approx(rec.floor_z_m, abs=1e-5)
    # 45 deg walls: 0.2 m inside the rim the ground is at most 0.2 m below the rim.
    rim = rec.floor_z_m + 0.6
    z_wall = float(new.height_at(np.array([[0.0, 6.7]]))[0])
    assert rim - 0.25 <= z_wall < rim


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"depth_m": 0.0}, "depth_m"),
        ({"depth_m": -0.5}, "depth_m"),
        ({"length_m": -1.0}, "length_m"),
        ({"width_m": float("inf")}, "width_m"),
        ({"kind": "hole"}, "kind"),
        ({"wall_slope_deg": 0.0}, "wall_slope_deg"),
        ({"station_m": None}, "station_m"),
        ({"xy_m": (0.0, 1.0)}, "station_m"),
    ],
)
def test_negative_spec_errors_name_the_field(kwargs: dict, field: str) -> None:
    base = {"station_m": 10.0} | kwargs
    with pytest.raises(ConfigError) as info:
        NegativeObstacleSpec(**base)
    assert info.value.field == field


def test_obstacle_outside_terrain_names_the_indexed_field() -> None:
    config = TerrainConfig(
        length_m=20.0,
        negative_obstacles=(
            NegativeObstacleSpec(station_m=5.0),
            NegativeObstacleSpec(station_m=5.0, lateral_m=40.0),
        ),
    )
    with pytest.raises(ConfigError) as info:
        generate_terrain(config, 0)
    assert info.value.field == "negative_obstacles[1].station_m"


def test_too_small_to_carve_names_the_field() -> None:
    config = TerrainConfig(
        length_m=20.0, negative_obstacles=(NegativeObstacleSpec(station_m=5.0, width_m=0.1),)
    )
    with pytest.raises(ConfigError) as info:
        generate_terrain(config, 0)
    assert info.value.field == "negative_obstacles[0].width_m"


def test_positive_box_sits_on_ground_and_cylinder_pedestrian() -> None:
    hf = _field()
    car = PositiveObstacleSpec(kind="vehicle", xy_m=(1.0, 8.0), yaw_deg=90.0)
    same, rec = place_positive_obstacle(
        hf, car, centre_xy_m=np.array([1.0, 8.0]), yaw_rad=math.pi / 2, obstacle_id="vehicle-0"
    )
    assert same.heights_m is hf.heights_m
    assert rec.shape == "box" and not rec.in_heightfield
    np.testing.assert_allclose(rec.half_extents_m, [0.9, 2.25, 0.75])
    footprint = obstacle_outline("pit", 4.5, 1.8, np.array([1.0, 8.0]), math.pi / 2)
    bottom = rec.centre_m[2] - rec.half_extents_m[2]
    assert bottom == pytest.approx(float(np.min(hf.height_at(np.vstack([footprint, [[1.0, 8.0]]])))))
    ped = PositiveObstacleSpec(kind="pedestrian", xy_m=(0.0, 5.0))
    _, rec = place_positive_obstacle(hf, ped, centre_xy_m=np.array([0.0, 5.0]), yaw_rad=0.0, obstacle_id="p")
    assert rec.shape == "cylinder"
    np.testing.assert_allclose(rec.half_extents_m, [0.3, 0.3, 0.85])


def test_mound_is_raised_into_heightfield() -> None:
    hf = _field(rough=False)
    spec = PositiveObstacleSpec(kind="mound", size_m=(4.0, 3.0, 0.6), xy_m=(0.0, 10.0))
    new, rec = place_positive_obstacle(
        hf, spec, centre_xy_m=np.array([0.0, 10.0]), yaw_rad=0.0, obstacle_id="m"
    )
    assert rec.in_heightfield
    assert new.heights_m.max() == pytest.approx(0.6, abs=1e-3)
    assert float(new.height_at(np.array([[0.0, 12.1]]))[0]) == pytest.approx(0.0)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"kind": "tree"}, "kind"),
        ({"size_m": (1.0, -1.0, 1.0)}, "size_m"),
        ({"size_m": (1.0, 1.0)}, "size_m"),
        ({"lateral_m": float("nan")}, "lateral_m"),
    ],
)
def test_positive_spec_errors_name_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        PositiveObstacleSpec(**({"station_m": 3.0} | kwargs))
    assert info.value.field == field


def test_sample_pit_spec_sizes_around_paper_sizes() -> None:
    rng = np.random.default_rng(0)
    specs = [sample_pit_spec(rng, station_m=10.0, size_jitter=0.2) for _ in range(200)]
    for spec in specs:
        ok = [
            0.8 * length <= spec.length_m <= 1.2 * length
            and max(0.8 * width, MIN_NEGATIVE_WIDTH_M) <= spec.width_m <= 1.2 * width
            for length, width in PAPER_N_PIT_SIZES_M
        ]
        assert any(ok)
        assert DEPTH_RANGE_M[0] <= spec.depth_m <= DEPTH_RANGE_M[1]
    assert len({round(s.length_m, 6) for s in specs}) > 100
    exact = sample_pit_spec(np.random.default_rng(1), station_m=0.0, size_jitter=0.0)
    assert (exact.length_m, exact.width_m) in PAPER_N_PIT_SIZES_M
    again = sample_pit_spec(np.random.default_rng(1), station_m=0.0, size_jitter=0.0)
    assert again == exact
    with pytest.raises(ConfigError, match="size_jitter"):
        sample_pit_spec(rng, station_m=0.0, size_jitter=1.0)
    with pytest.raises(ConfigError, match="depth_range_m"):
        sample_pit_spec(rng, station_m=0.0, depth_range_m=(0.5, 0.2))


_FLAT_SMALL = generate_terrain(
    TerrainConfig(length_m=10.0, corridor_width_m=12.0, roughness=RoughnessConfig.flat()), 0
).heightfield


@settings(max_examples=40, deadline=None)
@given(
    kind=st.sampled_from(["pit", "ditch", "trench", "crater"]),
    length_m=st.floats(0.3, 4.0),
    width_m=st.floats(0.3, 4.0),
    depth_m=st.floats(0.3, 1.5),
    x_m=st.floats(-2.0, 2.0),
    y_m=st.floats(2.0, 8.0),
    yaw_deg=st.floats(-180.0, 180.0),
)
def test_any_carve_floor_inside_untouched_outside(kind, length_m, width_m, depth_m, x_m, y_m, yaw_deg):
    hf = _FLAT_SMALL
    spec = NegativeObstacleSpec(
        kind=kind, length_m=length_m, width_m=width_m, depth_m=depth_m, xy_m=(x_m, y_m)
    )
    new, rec = carve_negative_obstacle(
        hf, spec, centre_xy_m=np.array([x_m, y_m]), yaw_rad=math.radians(yaw_deg), obstacle_id="o"
    )
    assert rec.floor_z_m == pytest.approx(-depth_m, abs=1e-6)
    assert _signed_area(rec.outline_xy_m) > 0
    changed = new.heights_m != hf.heights_m
    assert np.all(new.heights_m[changed] == np.float32(rec.floor_z_m))
    # Every changed sample lies inside the outline's bounding box (nothing carved outside).
    xy = _sample_xy(hf)[changed]
    lo, hi = rec.outline_xy_m.min(axis=0), rec.outline_xy_m.max(axis=0)
    assert np.all((xy >= lo - 1e-6) & (xy <= hi + 1e-6))
    # ... and the samples strictly inside the outline (away from the edges) are all carved.
    strictly_inside = points_in_polygon(_sample_xy(hf), rec.outline_xy_m)
    assert np.all(changed[strictly_inside] | (hf.heights_m[strictly_inside] == rec.floor_z_m))
    # The carved area is the outline's area to within a one-sample rim.
    perimeter = np.sum(
        np.linalg.norm(np.diff(np.vstack([rec.outline_xy_m, rec.outline_xy_m[:1]]), axis=0), axis=1)
    )
    area = _signed_area(rec.outline_xy_m)
    assert abs(changed.sum() * RES * RES - area) <= perimeter * RES + 1e-9
    assert float(new.height_at(np.array([[x_m, y_m]]))[0]) == pytest.approx(rec.floor_z_m, abs=0.02)
