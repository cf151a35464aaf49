"""Tests of the course's longitudinal profile: crests and dips as scenario data."""

from __future__ import annotations

import re

import numpy as np
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.sim.carving import NegativeObstacleSpec
from negobs_gym.sim.terrain import ProfileFeature, RoughnessConfig, TerrainConfig, generate_terrain
from negobs_gym.spec import ScenarioSpec
from negobs_gym.spec.scenario import spec_from_toml, spec_to_toml

SMALL = dict(length_m=60.0, corridor_width_m=16.0, lead_in_m=5.0, run_out_m=5.0)


def _spec(profile: list[dict]) -> dict:
    return {"name": "profile", "terrain": {"course": {"length_m": 80.0, "profile": profile}}}


def _flat(profile: tuple[ProfileFeature, ...], **kw) -> TerrainConfig:
    return TerrainConfig(**SMALL, roughness=RoughnessConfig.flat(), profile=profile, **kw)


def test_profile_round_trips_through_dict_and_toml():
    spec = ScenarioSpec.from_dict(
        _spec(
            [
                {"kind": "crest", "station_m": [30.0, 34.0], "height_m": 2.2, "length_m": 24.0},
                {"kind": "dip", "station_m": 60.0, "height_m": [0.5, 1.0], "length_m": 12.0},
            ]
        )
    )
    crest, dip = spec.terrain.course.profile
    assert crest.station_m == (30.0, 34.0) and dip.height_m == (0.5, 1.0) and dip.kind == "dip"
    assert ScenarioSpec.from_dict(spec.to_dict()) == spec
    text = spec_to_toml(spec)
    assert spec_from_toml(text) == spec
    toml_style = (
        'name = "profile"\n[terrain.course]\nlength_m = 80.0\n'
        '[[terrain.course.profile]]\nkind = "crest"\nstation_m = [30.0, 34.0]\n'
        "height_m = 2.2\nlength_m = 24.0\n"
        '[[terrain.course.profile]]\nkind = "dip"\nstation_m = 60.0\nheight_m = [0.5, 1.0]\nlength_m = 12.0\n'
    )
    assert spec_from_toml(toml_style) == spec


@pytest.mark.parametrize(
    ("entry", "name"),
    [
        ({"kind": "hill"}, "kind"),
        ({"length_m": 0.0}, "length_m"),
        ({"length_m": [-1.0, 5.0]}, "length_m"),
        ({"height_m": -0.5}, "height_m"),
        ({"height_m": [2.0, 1.0]}, "height_m"),
        ({"station_m": 95.0}, "station_m"),  # past the course's 80 m
        ({"station_m": [70.0, 81.0]}, "station_m"),  # the range's high end off the course
        ({"station_m": -1.0}, "station_m"),
        ({"station_m": "far"}, "station_m"),
        ({"slope": 3.0}, "slope"),
    ],
)
def test_bad_profile_is_named_by_field(entry, name):
    feature = {"kind": "crest", "station_m": 40.0, "height_m": 1.0, "length_m": 10.0, **entry}
    with pytest.raises(ConfigError) as err:
        ScenarioSpec.from_dict(_spec([{"kind": "crest", "station_m": 10.0}, feature]))
    assert re.fullmatch(rf"terrain\.course\.profile(\[1\]|\.1)\.{name}", err.value.field), err.value.field


def test_drawn_profile_is_deterministic_and_follows_the_seed():
    spec = ScenarioSpec.from_dict(
        _spec([{"kind": "crest", "station_m": [20.0, 40.0], "height_m": [1.0, 3.0], "length_m": 20.0}])
    )

    def draw(seed: int):
        terrain = spec.sample(np.random.default_rng(seed)).terrain
        return terrain.metadata["profile"][0], terrain.heightfield.heights_m

    (a, ha), (b, hb), (c, _) = draw(5), draw(5), draw(6)
    assert a == b and np.array_equal(ha, hb)
    assert isinstance(a.station_m, float) and 20.0 <= a.station_m <= 40.0 and 1.0 <= a.height_m <= 3.0
    assert (a.station_m, a.height_m) != (c.station_m, c.height_m)


def test_heightfield_has_the_crest_and_the_dip_at_their_stations():
    crest = ProfileFeature(kind="crest", station_m=20.0, height_m=2.2, length_m=24.0)
    dip = ProfileFeature(kind="dip", station_m=45.0, height_m=0.8, length_m=10.0)
    terrain = generate_terrain(_flat((crest, dip)), seed=1)
    hf, track = terrain.heightfield, terrain.track
    for lateral in (0.0, -2.5, 4.0, -7.0):  # track, its edge, verge and the corridor's side
        at = lambda s, lat=lateral: float(hf.height_at(track.pose_at(s, lat)[0]))  # noqa: E731
        assert at(20.0) == pytest.approx(2.2, abs=1e-3)
        assert at(20.0 + 6.0) == pytest.approx(1.1, abs=2e-3)  # half-way down: half the height
        assert at(8.0) == pytest.approx(0.0, abs=1e-3) and at(32.0) == pytest.approx(0.0, abs=1e-3)
        assert at(45.0) == pytest.approx(-0.8, abs=1e-3)
    assert np.max(hf.heights_m) == pytest.approx(2.2, abs=1e-3)


def test_profile_leaves_the_rest_of_the_course_bit_for_bit():
    rough = dict(SMALL)
    plain = generate_terrain(TerrainConfig(**rough), seed=3)
    crest = ProfileFeature(kind="crest", station_m=[30.0, 31.0], height_m=1.0, length_m=10.0)
    crested = generate_terrain(TerrainConfig(**rough, profile=(crest,)), seed=3)
    hf = plain.heightfield
    ys = hf.origin_m[1] + hf.resolution_m * np.arange(hf.shape[0])
    far = np.abs(ys - 30.5) > 8.0  # rows well outside the crest's span (the track runs along +Y)
    assert np.array_equal(plain.heightfield.heights_m[far], crested.heightfield.heights_m[far])
    assert not np.array_equal(plain.heightfield.heights_m, crested.heightfield.heights_m)


def test_pit_on_a_crest_sits_on_the_displaced_ground():
    crest = ProfileFeature(kind="crest", station_m=20.0, height_m=2.0, length_m=24.0)
    pit = NegativeObstacleSpec(kind="pit", length_m=1.0, width_m=1.0, depth_m=0.8, station_m=23.0)
    terrain = generate_terrain(_flat((crest,), negative_obstacles=(pit,)), seed=0)
    (record,) = terrain.negative_obstacles
    ground = 2.0 * 0.5 * (1.0 + np.cos(2.0 * np.pi * 3.0 / 24.0))  # the crest's height at 23 m
    assert record.floor_z_m == pytest.approx(ground - 0.8, abs=0.05)
    centre = terrain.track.pose_at(23.0)[0]
    assert float(terrain.heightfield.height_at(centre)) == pytest.approx(record.floor_z_m, abs=1e-3)
