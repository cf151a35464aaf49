"""Every preset builds, puts its obstacles where asked and sets start and goal."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.sim import presets
from negobs_gym.sim.terrain import track_coordinates

RES = 0.2  # coarse grids keep these tests fast; the geometry is resolution independent


@pytest.mark.parametrize("name", sorted(presets.PRESETS))
def test_every_preset_builds_with_start_goal_on_terrain(name: str) -> None:
    terrain = presets.PRESETS[name](seed=1, resolution_m=RES)
    assert terrain.start_xy_yaw == (0.0, 0.0, 0.0)
    x0, x1, y0, y1 = terrain.heightfield.extent_m
    gx, gy = terrain.goal_xy_m
    assert x0 < gx < x1 and y0 < gy < y1
    assert np.all(np.isfinite(terrain.heightfield.heights_m))
    ids = [o.obstacle_id for o in terrain.negative_obstacles + terrain.positive_obstacles]
    assert len(ids) == len(set(ids))


def test_braking_track_ditch_near_edge_distance_size_and_depth() -> None:
    terrain = presets.braking_track(
        ditch_distance_m=30.0,
        ditch_length_m=1.0,
        ditch_width_m=3.0,
        ditch_depth_m=0.8,
        lateral_offset_m=0.8,
        seed=0,
        rough=False,
        resolution_m=0.1,
    )
    (ditch,) = terrain.negative_obstacles
    assert ditch.obstacle_id == "ditch-0" and ditch.depth_m == 0.8
    lo, hi = ditch.outline_xy_m.min(axis=0), ditch.outline_xy_m.max(axis=0)
    np.testing.assert_allclose(lo, [0.8 - 1.5, 30.0], atol=1e-9)
    np.testing.assert_allclose(hi, [0.8 + 1.5, 31.0], atol=1e-9)
    assert ditch.floor_z_m == pytest.approx(-0.8)
    assert float(terrain.heightfield.height_at(np.array([[0.8, 30.5]]))[0]) == pytest.approx(-0.8)
    # Flat elsewhere: the road before the ditch is at 0.
    assert np.all(terrain.heightfield.height_at(np.array([[0.0, y] for y in range(0, 29)])) == 0)


def test_braking_track_rough_is_deterministic() -> None:
    a = presets.braking_track(seed=4, resolution_m=RES)
    b = presets.braking_track(seed=4, resolution_m=RES)
    assert a.heightfield.heights_m.tobytes() == b.heightfield.heights_m.tobytes()
    assert a.negative_obstacles[0].floor_z_m == b.negative_obstacles[0].floor_z_m


def test_trench_crossing_spans_the_track() -> None:
    terrain = presets.trench_crossing(seed=0, trench_distance_m=25.0, resolution_m=RES)
    (trench,) = terrain.negative_obstacles
    s, lat = track_coordinates(terrain.track, trench.outline_xy_m)
    assert s.min() == pytest.approx(25.0, abs=1e-6) and s.max() == pytest.approx(28.0, abs=1e-6)
    assert lat.min() < -terrain.track.width_m / 2 and lat.max() > terrain.track.width_m / 2


def test_rough_track_has_no_obstacles_and_is_long_enough() -> None:
    terrain = presets.rough_track(length_m=200.0, seed=2, resolution_m=RES)
    assert terrain.negative_obstacles == () and terrain.positive_obstacles == ()
    assert terrain.track.length_m == pytest.approx(200.0)


def test_paper_t_scenes_put_obstacles_where_asked() -> None:
    car = presets.oncoming_car(seed=0, car_distance_m=35.0, resolution_m=RES).positive_obstacles[0]
    assert car.kind == "vehicle"
    np.testing.assert_allclose(car.centre_m[:2], [-1.5, 35.0], atol=1e-9)
    assert car.yaw_rad == pytest.approx(np.pi)
    bike = presets.parked_motorbike(seed=0, resolution_m=RES).positive_obstacles[0]
    assert bike.kind == "motorbike" and bike.centre_m[0] > 0  # right side of the track
    scene = presets.pedestrian_near_dropoff(seed=0, resolution_m=RES)
    ped = scene.positive_obstacles[0]
    assert ped.shape == "cylinder" and scene.track.border_kinds[1] == "dropoff"
    # Ground beyond the pedestrian (further right) drops by ~1.5 m.
    z_near, z_far = scene.heightfield.height_at(np.array([[ped.centre_m[0], 25.0], [8.0, 25.0]]))
    assert z_near - z_far > 1.0
    banked = presets.straight_banked_track(seed=0, resolution_m=RES)
    assert banked.track.border_kinds == ("bank", "bank")


def test_bend_turns_left_by_the_angle() -> None:
    terrain = presets.bend(seed=0, angle_deg=60.0, resolution_m=RES)
    _, yaw = terrain.track.pose_at(terrain.track.length_m - 1.0)
    assert float(yaw) == pytest.approx(np.radians(60.0), abs=1e-3)


def test_winding_course_mixed_obstacles_and_seed_dependence() -> None:
    a = presets.winding_course(seed=5, resolution_m=RES)
    b = presets.winding_course(seed=6, resolution_m=RES)
    assert len(a.negative_obstacles) == 6 and len(a.positive_obstacles) == 4
    assert len(a.track.centreline_xy_m) > 2
    s, lat = track_coordinates(a.track, np.array([o.centre_xy_m for o in a.negative_obstacles]))
    assert np.all((s > 15.0) & (s < a.track.length_m)) and np.all(np.abs(lat) <= 2.0 + 1e-6)
    assert not np.array_equal(a.track.centreline_xy_m, b.track.centreline_xy_m)


def test_bad_preset_arguments_raise_config_error() -> None:
    with pytest.raises(ConfigError) as info:
        presets.braking_track(ditch_depth_m=0.0, resolution_m=RES)
    assert info.value.field == "depth_m"
    with pytest.raises(ConfigError) as info:
        presets.braking_track(lateral_offset_m=30.0, resolution_m=RES)
    assert info.value.field == "negative_obstacles[0].station_m"


def test_clutter_track_kinds_keep_the_centre_clear_and_pits_on_it() -> None:
    terrain = presets.clutter_track(seed=2, pits=True, length_m=100.0, resolution_m=RES)
    kinds = {o.kind for o in terrain.positive_obstacles}
    assert {"box", "vehicle", "rock", "pole"} <= kinds
    poles = [o for o in terrain.positive_obstacles if o.kind == "pole"]
    assert len(poles) > 30 and all(o.shape == "cylinder" and o.half_extents_m[0] <= 0.1 for o in poles)
    _s, lat = track_coordinates(terrain.track, np.array([o.centre_m[:2] for o in terrain.positive_obstacles]))
    half_width = np.array([min(o.half_extents_m[:2]) for o in terrain.positive_obstacles])
    assert np.all(np.abs(lat) - half_width >= 1.0)  # the vehicle's 1.8 m wide lane stays clear
    assert terrain.track.border_kinds[0] == "bank"  # the embankment beside the walls
    _s_pit, lat_pit = track_coordinates(
        terrain.track, np.array([o.centre_xy_m for o in terrain.negative_obstacles])
    )
    assert len(terrain.negative_obstacles) == 3 and np.all(np.abs(lat_pit) < 0.1)
    bare = presets.clutter_track(seed=2, clutter=("rocks",), resolution_m=RES)
    assert {o.kind for o in bare.positive_obstacles} == {"rock"} and bare.negative_obstacles == ()
    again = presets.clutter_track(seed=2, pits=True, length_m=100.0, resolution_m=RES)
    assert [o.centre_m.tolist() for o in again.positive_obstacles] == [
        o.centre_m.tolist() for o in terrain.positive_obstacles
    ]
    with pytest.raises(ConfigError) as info:
        presets.clutter_track(clutter=("trees",))
    assert info.value.field == "clutter"
