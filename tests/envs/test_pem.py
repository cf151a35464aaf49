"""The ``pem`` grid source: determinism, spaces, the model file and its mismatch error, hazards."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.envs import make_env
from negobs_gym.envs.pem import PerceptionErrorModel
from negobs_gym.errors import ConfigError
from tests.envs.test_pem_model import constant_model as _model

ENV = "negobs_gym/Braking-v1"
ACTIONS = [np.array([0.6, 0.1 * k], np.float32) for k in range(-3, 4)]


def _drive(env, seed: int, steps: int = len(ACTIONS)) -> list[dict]:
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for action in ACTIONS[:steps]:
        obs, *_ = env.step(action)
        out.append(obs)
    return out


def _pem_env(tmp_path, model: PerceptionErrorModel, *extra: str, env: str = ENV):
    path = model.save(tmp_path / "pem.json")
    return make_env(env, ["observation.source=pem", f"observation.pem_model={path}", *extra])


def test_same_seed_same_grids_and_the_oracles_episode():
    """Bit for bit per seed; terrain, start and physics draw as under the oracle (own child rng)."""
    pem_a, pem_b = (make_env(ENV, ["observation.source=pem"]) for _ in range(2))
    oracle = make_env(ENV, ["observation.source=oracle"])
    try:
        a, b, o = _drive(pem_a, 5), _drive(pem_b, 5), _drive(oracle, 5)
        assert all(np.array_equal(x["grid"], y["grid"]) for x, y in zip(a, b, strict=True))
        assert all(np.array_equal(x["state"], y["state"]) for x, y in zip(a, b, strict=True))
        assert all(np.array_equal(x["state"], y["state"]) for x, y in zip(a, o, strict=True))
        assert pem_a.unwrapped.terrain.seed == oracle.unwrapped.terrain.seed
        # channels the PEM does not model are the oracle's
        channels = pem_a.unwrapped.scenario.observation.channels
        drawn = [i for i, c in enumerate(channels) if c not in ("negative", "positive")]
        assert drawn and all(
            np.array_equal(x["grid"][drawn], y["grid"][drawn]) for x, y in zip(a, o, strict=True)
        )
        assert pem_a.observation_space == make_env(ENV).observation_space
        assert all(pem_a.observation_space.contains(x) for x in a)
        again = _drive(pem_a, 5)  # a kept world (and its cached terrain classes): the same episode
        assert all(np.array_equal(x["grid"], y["grid"]) for x, y in zip(a, again, strict=True))
    finally:
        for env in (pem_a, pem_b, oracle):
            env.close()


def test_a_perfect_model_draws_the_oracle_and_a_blind_one_nothing(tmp_path):
    perfect = _pem_env(tmp_path, _model(1.0))
    blind = _pem_env(tmp_path / "b", _model(0.0))
    oracle = make_env(ENV, ["observation.source=oracle"])
    try:
        got, truth, none = _drive(perfect, 2), _drive(oracle, 2), _drive(blind, 2)
        assert any(t["grid"][0].any() for t in truth)  # the ditch is on the grid
        for g, t, n in zip(got, truth, none, strict=True):
            np.testing.assert_array_equal(g["grid"][0], t["grid"][0])
            assert not n["grid"][0].any()
    finally:
        for env in (perfect, blind, oracle):
            env.close()


def test_the_positive_channel_is_the_models_and_the_oracles_without_one(tmp_path):
    """A perfect positive channel draws the oracle's footprints, a blind one nothing, a model
    without the channel the oracle's; the safety filter's positive cells are the drawn ones."""
    scene = "rock_on_track_25kmh"  # a rock on the driving line, seen by paper T's channel as fitted
    lux = "observation.positive_detector=traversable"
    near = "positive_obstacles.0.station_m=15"  # on the grid from the start
    perfect = _pem_env(tmp_path, _model(1.0, positive=1.0), lux, near, env=scene)
    blind = _pem_env(tmp_path / "b", _model(1.0, positive=0.0), lux, near, env=scene)
    legacy = _pem_env(tmp_path / "n", _model(1.0), lux, near, env=scene)
    oracle = make_env(scene, ["observation.source=oracle", lux, near])
    try:
        index = perfect.unwrapped.scenario.observation.channels.index("positive")
        got, none, old, truth = (_drive(e, 2) for e in (perfect, blind, legacy, oracle))
        assert any(t["grid"][index].any() for t in truth)
        for g, n, o, t in zip(got, none, old, truth, strict=True):
            np.testing.assert_array_equal(g["grid"][index], t["grid"][index])
            np.testing.assert_array_equal(o["grid"][index], t["grid"][index])
            assert not n["grid"][index].any()
        assert len(perfect.unwrapped.hazard_state().positive_obstacles_xy_m) > 0
        assert len(blind.unwrapped.hazard_state().positive_obstacles_xy_m) == 0
    finally:
        for env in (perfect, blind, legacy, oracle):
            env.close()


def test_offsets_move_the_near_edge_and_false_alarms_appear(tmp_path):
    base = _pem_env(tmp_path, _model(1.0))
    late = _pem_env(tmp_path / "late", _model(1.0, near=0.6))
    noisy = _pem_env(tmp_path / "fa", _model(0.0, density=0.05))
    try:
        for env in (base, late, noisy):
            env.reset(seed=2)
        for _ in range(60):  # on until the whole ditch is on the grid, the same drive in each env
            cells = base.unwrapped.hazard_state().negative_obstacles_xy_m
            if len(cells) and cells[:, 1].min() < 18.0:
                break
            for env in (base, late, noisy):
                env.step(ACTIONS[3])
        near = [e.unwrapped.hazard_state().negative_obstacles_xy_m[:, 1].min() for e in (base, late)]
        assert near[1] - near[0] == pytest.approx(0.6, abs=0.21)  # one 20 cm cell of rounding
        assert len(noisy.unwrapped.hazard_state().negative_obstacles_xy_m) > 0  # no pit drawn: all false
    finally:
        for env in (base, late, noisy):
            env.close()


def test_hazards_are_the_pems_own_cells_with_no_detector():
    env = make_env(ENV, ["observation.source=pem"])
    try:
        obs, _ = env.reset(seed=2)
        for action in ACTIONS[:3]:
            obs, *_ = env.step(action)
        hazards = env.unwrapped.hazard_state()
        assert env.unwrapped.perception is None  # no detector was started beside it
        layer = env.unwrapped._grid_source.grid
        assert layer.grid == env.unwrapped.scenario.observation.grid
        cells = env.unwrapped.scenario.observation.grid.cell_of(hazards.negative_obstacles_xy_m)
        pooled = np.zeros_like(obs["grid"][0])
        k = env.unwrapped.scenario.observation.downsample
        pooled[cells[0] // k, cells[1] // k] = 1
        np.testing.assert_array_equal(pooled, obs["grid"][0])
    finally:
        env.close()


def test_settings_that_differ_from_the_fit_are_refused_by_name(tmp_path):
    path = _model(0.5).save(tmp_path / "pem.json")
    with pytest.raises(ConfigError) as error:
        make_env(
            ENV,
            ["observation.source=pem", f"observation.pem_model={path}", "observation.tighten_pairs=false"],
        )
    assert error.value.field == "observation.pem_model"
    assert "detector.fusion.tighten_on_match" in str(error.value)


def test_pem_is_selected_like_the_other_sources():
    from negobs_gym.cli import build_parser
    from negobs_gym.envs import source_overrides
    from negobs_gym.policies.config import source_settings

    assert source_overrides("pem") == ["observation.source=pem"]
    assert source_settings("pem") == (("observation.source=pem",), True)
    args = build_parser().parse_args(["eval", "policy", "model.zip", "--source", "pem"])
    assert args.source == "pem"
    env = make_env(ENV, source_overrides("pem"))
    try:
        assert env.unwrapped.scenario.observation.source == "pem"
    finally:
        env.close()


def test_the_structure_channels_scenario_draws_from_its_own_shipped_model():
    from negobs_gym.envs.pem import DEFAULT_PEM_PATH, load_pem, shipped_pem_path
    from negobs_gym.envs.sources import make_grid_source

    env = make_env("offroad_nav_v2_structure", ["observation.source=pem"])
    try:
        observation = env.unwrapped.scenario.observation
        obs, _ = env.reset(seed=3)
        for _ in range(3):
            obs, *_ = env.step(np.array([0.5, 0.0], np.float32))
        assert env.observation_space.contains(obs)
    finally:
        env.close()
    model = make_grid_source(observation).model
    assert model == load_pem(shipped_pem_path(observation), observation)
    assert model.positive != PerceptionErrorModel.from_json(DEFAULT_PEM_PATH.read_text()).positive
