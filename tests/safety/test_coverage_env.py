"""The envs' coverage as the filter reads it: cells hidden behind a crest are unobserved."""

from __future__ import annotations

import numpy as np

from negobs_gym.envs import make_env
from negobs_gym.safety import Corridor, observed_clear_distance
from negobs_gym.spec import ScenarioSpec

TOP_M = 30.0  # station of the crest's top
START_M = 22.0  # the car stands 8 m before it


def _spec(crest: bool) -> ScenarioSpec:
    profile = [{"kind": "crest", "station_m": TOP_M, "height_m": 2.2, "length_m": 24.0}] if crest else []
    return ScenarioSpec.from_dict(
        {
            "name": "crest_coverage",
            "terrain": {
                "course": {
                    "length_m": 70.0,
                    "roughness": {"slope_amplitude_m": 0.0, "bump_amplitude_m": 0.05},
                    "profile": profile,
                }
            },
            "start": {"station_m": START_M},
            "observation": {"sensor_noise": False},
        }
    )


def _state(crest: bool):
    env = make_env(_spec(crest))
    try:
        env.reset(seed=0)
        return env.unwrapped.hazard_state()
    finally:
        env.close()


def test_cells_behind_a_crest_are_unobserved():
    flat, crested = _state(False), _state(True)
    assert crested.observed is not None and crested.observed.shape == crested.grid.shape
    car = {"wheelbase_m": crested.wheelbase_m, "front_length_m": crested.front_length_m}
    corridor = Corridor(steer_rad=0.0, half_width_m=1.2, **car)
    centres = crested.grid.cell_centres()
    # the track's band 4-14 m past the top: 12-22 m ahead of the rear axle, down the crest's far side
    behind = (np.abs(centres[..., 0]) <= 1.2) & (centres[..., 1] >= 12.0) & (centres[..., 1] <= 22.0)
    assert flat.observed[behind].mean() > 0.5  # flat ground there: mostly measured
    assert crested.observed[behind].mean() < 0.05  # behind the crest: hardly a return
    clear = observed_clear_distance(corridor, crested.grid, crested.observed, crested.negative_obstacles_xy_m)
    assert clear.end == "unobserved" and clear.distance_m < TOP_M - START_M + 4.0
    open_ground = observed_clear_distance(corridor, flat.grid, flat.observed, flat.negative_obstacles_xy_m)
    assert open_ground.distance_m > 10.0
