"""The shipped blind-crest scene hides its pit from the roof HDL-64 until it is within R(25 km/h)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from negobs_gym.safety import braking_distance_m
from negobs_gym.sensors.rigs import paper_n_rig
from negobs_gym.sim.terrain import RoughnessConfig, generate_terrain
from negobs_gym.spec import load_scenario

WHEELBASE_M = 2.8  # negobs_gym.sim.vehicle.VehicleConfig


def _first_sight_m(terrain, rim_station_m: float) -> float:
    """Rear axle to the pit's near rim [m] when the roof HDL-64 first has a line of sight to the
    rim: the car on the centre line pitched along the chord between its axles, the sensor its
    mount height above the rear axle along the body's normal, the ray above the lowest laser and
    above the ground all the way (a pure line-of-sight bound: the detector needs more)."""
    mount = next(m for m in paper_n_rig().mounts if m.name == "hdl64")
    height = mount.translation_m[2]
    lowest = math.radians(min(mount.model.elevation_deg))
    track, hf = terrain.track, terrain.heightfield

    def ground(s: np.ndarray) -> np.ndarray:
        return hf.height_at(track.pose_at(np.asarray(s, dtype=float))[0])

    rim_z = float(ground(rim_station_m))
    for gap in np.arange(25.0, 0.0, -0.1):
        rear = rim_station_m - gap
        z_rear, z_front = ground([rear, rear + WHEELBASE_M])
        pitch = math.atan2(z_front - z_rear, WHEELBASE_M)
        sx, sz = rear - height * math.sin(pitch), z_rear + height * math.cos(pitch)
        if math.atan2(rim_z - sz, rim_station_m - sx) - pitch < lowest:
            continue  # below the lowest laser
        s = np.linspace(sx, rim_station_m - 0.3, 300)
        if np.all(ground(s) < sz + (rim_z - sz) * (s - sx) / (rim_station_m - sx)):
            return float(gap)
    return 0.0


@pytest.mark.parametrize("past_top_m", [2.0, 4.0, 6.0, 7.0])
def test_the_crest_hides_the_pit_until_it_is_within_r_at_25_kmh(past_top_m):
    spec = load_scenario("pit_past_a_crest_25kmh")
    (crest,) = spec.terrain.course.profile
    (pit,) = spec.obstacles
    lo, hi = pit.station_m.low, pit.station_m.high  # the pit's centre: rim 2-8 m past the top
    assert (lo - 0.5 * pit.length_m, hi - 0.5 * pit.length_m) == (
        crest.station_m + 2.0,
        crest.station_m + 8.0,
    )
    course = dataclasses.replace(spec.terrain.course, roughness=RoughnessConfig.flat())
    terrain = generate_terrain(course, seed=0)
    sight = _first_sight_m(terrain, crest.station_m + past_top_m)
    assert 0.0 < sight < float(braking_distance_m(25 / 3.6))
