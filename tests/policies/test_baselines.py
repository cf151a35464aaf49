"""Shipped trained policies: their records, their loading, and names in place of model paths."""

from __future__ import annotations

from pathlib import Path

import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.policies.baselines import baseline_names, baseline_record, resolve_model


def test_a_path_resolves_to_itself_and_an_unknown_name_is_refused(tmp_path: Path) -> None:
    model = tmp_path / "m.zip"
    model.write_bytes(b"not read here")
    assert resolve_model(str(model)) == str(model)
    assert resolve_model(str(tmp_path / "m")) == str(tmp_path / "m")  # SB3 adds .zip itself
    with pytest.raises(ConfigError, match="no shipped baseline"):
        resolve_model("no_such_policy")
    with pytest.raises(ConfigError, match="no shipped baseline"):
        baseline_record("no_such_policy")


@pytest.mark.parametrize("name", baseline_names())
def test_each_shipped_baseline_has_its_record_and_runs_on_its_env(name: str, tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    import negobs_gym  # noqa: F401 - registers the envs
    from negobs_gym.policies.observation import match_observation
    from negobs_gym.policies.training import make_task_env
    from negobs_gym.scenarios import env_with_overrides

    record = baseline_record(name)
    for key in ("command", "seed", "steps", "wall_s", "env", "evaluation"):
        assert key in record, f"{name}.json lacks {key!r}"
    assert record["command"].startswith("negobs train ")
    settings = record.get("set", [])  # the --set its commands carry
    assert all(f"--set {s}" in record["command"] for s in settings)
    model = PPO.load(resolve_model(name), device="cpu")
    env = make_task_env(env_with_overrides(record["env"], settings, tmp_path), None)  # id or scenario
    obs, _ = env.reset(seed=1_000_000)
    action, _ = model.predict(match_observation(obs, model.observation_space), deterministic=True)
    assert env.action_space.contains(action.astype(env.action_space.dtype))
    env.close()


def test_at_least_one_baseline_is_shipped() -> None:
    assert baseline_names(), "no trained policy under negobs_gym/policies/trained"
