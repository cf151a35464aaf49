"""Phantom ``negative`` clusters in the oracle grid: where they lie, when they show, what they leave alone."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.core.geometry import vehicle_to_world_xy
from negobs_gym.core.pose import Pose
from negobs_gym.envs import make_env
from negobs_gym.envs.phantoms import Phantoms
from negobs_gym.envs.scenarios import OffroadNavV1Env
from negobs_gym.errors import ConfigError
from negobs_gym.sim.types import Track
from negobs_gym.spec import ObservationConfig, PhantomConfig, ScenarioSpec
from negobs_gym.spec.overrides import apply_overrides, spec_for_env


def _straight_track(length_m: float = 200.0, width_m: float = 6.0) -> Track:
    """A track north along world +Y from the origin (yaw 0 faces +Y; lateral > 0 is +X)."""
    return Track(centreline_xy_m=np.array([[0.0, 0.0], [0.0, length_m]]), width_m=width_m)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("per_100m", -1.0),
        ("per_100m", float("nan")),
        ("per_100m", True),
        ("beyond_edge_m", (3.0, 1.0)),
        ("beyond_edge_m", (-1.0, 1.0)),
        ("across_m", (0.0, 1.0)),
        ("along_m", (1.0,)),
        ("range_m", (12.0, float("inf"))),
        ("show_probability", 1.5),
        ("show_probability", float("nan")),
    ],
)
def test_bad_phantom_settings_name_their_field(field: str, value) -> None:
    with pytest.raises(ConfigError, match=field):
        PhantomConfig(**{field: value})


def test_phantoms_lie_beside_the_track_within_the_drawn_distance() -> None:
    config = PhantomConfig(per_100m=20.0, beyond_edge_m=(1.0, 2.0), across_m=(0.4, 0.8), along_m=(1.0, 3.0))
    track = _straight_track()
    phantoms = Phantoms(config, track, np.random.default_rng(3))
    assert 20 <= len(phantoms) <= 60  # Poisson(40)
    beyond = np.abs(phantoms.centres_xy_m[:, 0]) - phantoms.half_sizes_m[:, 0] - 0.5 * track.width_m
    assert np.all((beyond >= 1.0 - 1e-9) & (beyond <= 2.0 + 1e-9))
    assert np.any(phantoms.centres_xy_m[:, 0] > 0) and np.any(phantoms.centres_xy_m[:, 0] < 0)
    across, along = phantoms.half_sizes_m.T
    assert np.all((across >= 0.2) & (across <= 0.4)) and np.all((along >= 0.5) & (along <= 1.5))
    assert len(Phantoms(PhantomConfig(per_100m=0.0), track, np.random.default_rng(3))) == 0


def test_a_phantom_in_a_bend_never_lands_on_the_track() -> None:
    # a hairpin: beside one leg, 4 m out, is the other leg's track
    centre = np.array([[0.0, 0.0], [0.0, 50.0], [7.0, 50.0], [7.0, 0.0]])
    track = Track(centreline_xy_m=centre, width_m=6.0)
    config = PhantomConfig(per_100m=50.0, beyond_edge_m=(0.5, 1.5))
    phantoms = Phantoms(config, track, np.random.default_rng(0))
    assert len(phantoms) > 0
    seg_x = np.array([0.0, 7.0])
    straight = phantoms.centres_xy_m[:, 1] < 48.0
    gap = np.abs(phantoms.centres_xy_m[straight, 0][:, None] - seg_x[None]).min(axis=1)
    assert np.all(gap >= 3.0)  # none between the legs, where both tracks cover the ground


def test_a_phantom_shows_only_within_its_range_and_covers_its_rectangle() -> None:
    config = PhantomConfig(per_100m=1.0, range_m=(12.0, 16.0), show_probability=1.0)
    phantoms = Phantoms(config, _straight_track(), np.random.default_rng(0))
    phantoms.centres_xy_m = np.array([[5.0, 100.0]])
    phantoms.yaws_rad = np.array([0.0])
    phantoms.half_sizes_m = np.array([[0.35, 0.55]])  # across (x), along (y); no cell centre on an edge
    cells = ObservationConfig().grid.cell_centres().reshape(-1, 2)
    for y_vehicle, expect_shown in ((80.0, False), (86.5, True), (88.0, True), (91.0, False)):
        pose = Pose(x=0.0, y=y_vehicle, yaw=0.0)
        covered = phantoms.layer(pose, cells)
        assert covered.any() == expect_shown, y_vehicle
        if expect_shown:
            world = vehicle_to_world_xy(cells, (pose.x, pose.y), pose.yaw)
            in_box = (np.abs(world[:, 0] - 5.0) <= 0.35) & (np.abs(world[:, 1] - 100.0) <= 0.55)
            np.testing.assert_array_equal(covered, in_box)
            assert 4 * 5 <= covered.sum() <= 4 * 6  # 20 cm cells in a 0.7 x 1.1 m rectangle


def test_show_probability_sets_how_often_a_phantom_in_range_shows() -> None:
    cells = ObservationConfig().grid.cell_centres().reshape(-1, 2)
    pose = Pose(x=0.0, y=90.0, yaw=0.0)
    shown = {}
    for p in (0.0, 0.3, 1.0):
        config = PhantomConfig(per_100m=1.0, show_probability=p)
        phantoms = Phantoms(config, _straight_track(), np.random.default_rng(1))
        phantoms.centres_xy_m, phantoms.yaws_rad = np.array([[5.0, 104.0]]), np.array([0.0])
        phantoms.half_sizes_m = np.array([[0.3, 0.3]])
        shown[p] = np.mean([phantoms.layer(pose, cells).any() for _ in range(400)])
    assert shown[0.0] == 0.0 and shown[1.0] == 1.0
    assert 0.22 <= shown[0.3] <= 0.38


def _v1_oracle(phantoms: PhantomConfig) -> OffroadNavV1Env:
    """OffroadNav-v1 on the oracle grid, on its shortest course (60 m: a world builds ~4x faster)."""
    settings = {
        f"observation.phantoms.{f.name}": getattr(phantoms, f.name) for f in dataclasses.fields(phantoms)
    }
    short = {"terrain.params.length_m": 60.0}
    return OffroadNavV1Env(overrides={"observation.source": "oracle", **short, **settings})


def test_phantoms_add_negative_cells_and_leave_rewards_and_rules_alone() -> None:
    plain = _v1_oracle(PhantomConfig())
    haunted = _v1_oracle(PhantomConfig(per_100m=30.0, show_probability=0.8))
    action = np.array([0.3, 0.0], np.float32)
    added = 0
    for seed in (5, 6):
        obs_p, _ = plain.reset(seed=seed)
        obs_h, _ = haunted.reset(seed=seed)
        assert plain.unwrapped._grid_source.phantoms is None
        for _ in range(60):
            obs_p, r_p, term_p, trunc_p, info_p = plain.step(action)
            obs_h, r_h, term_h, trunc_h, info_h = haunted.step(action)
            assert (r_p, term_p, trunc_p) == (r_h, term_h, trunc_h)
            assert info_p["rewards"] == info_h["rewards"]
            assert info_p.get("termination") == info_h.get("termination")
            np.testing.assert_array_equal(obs_p["state"], obs_h["state"])
            assert np.all(obs_h["grid"] >= obs_p["grid"])  # phantoms only add cells
            np.testing.assert_array_equal(obs_p["grid"][1], obs_h["grid"][1])  # positive untouched
            added += int(obs_h["grid"][0].sum()) - int(obs_p["grid"][0].sum())
            if term_p or trunc_p:
                break
    assert added > 0


def test_same_seed_same_phantoms_bit_for_bit() -> None:
    grids = []
    for _ in range(2):
        env = _v1_oracle(PhantomConfig(per_100m=30.0))
        env.reset(seed=9)
        grids.append(np.stack([env.step(np.array([0.3, 0.0], np.float32))[0]["grid"] for _ in range(25)]))
    np.testing.assert_array_equal(grids[0], grids[1])
    assert grids[0][:, 0].sum() > 0


def test_phantoms_are_a_scenario_setting_for_set() -> None:
    spec = apply_overrides(spec_for_env("negobs_gym/OffroadNav-v1"), ["observation.phantoms.per_100m=4"])
    assert spec.observation.phantoms == PhantomConfig(per_100m=4.0)
    assert ScenarioSpec.from_dict(spec.to_dict()) == spec
    with pytest.raises(ConfigError, match=r"observation\.phantoms\.show_probability"):
        apply_overrides(spec, ["observation.phantoms.show_probability=2"])
    env = make_env(
        "negobs_gym/OffroadNav-v1", ["observation.source=oracle", "observation.phantoms.per_100m=4"]
    )
    assert env.unwrapped.scenario.observation.phantoms.per_100m == 4.0
    env.close()
