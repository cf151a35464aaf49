"""The shipped policies' records against today's code: their settings parse, their observation
space is today's env's, they name the code and grid they were fitted on; renamed names warn,
retired ones say what to use instead."""

from __future__ import annotations

import warnings

import pytest

from negobs_gym.drivers.zoo import (
    RENAMED,
    RETIRED,
    baseline_names,
    baseline_record,
    recorded_env,
    resolve_model,
)
from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import config_from_record


def _model_space(path: str):
    """The observation space a saved SB3 model was trained on (read from its zip)."""
    from stable_baselines3.common.save_util import load_from_zip_file

    data, _, _ = load_from_zip_file(path, device="cpu", print_system_info=False)
    return data["observation_space"]


@pytest.mark.parametrize("name", baseline_names())
def test_each_records_settings_parse_and_its_observation_space_is_todays(name: str) -> None:
    from negobs_gym.policies.training import make_training_env
    from negobs_gym.spec import apply_overrides, spec_for_env

    record = baseline_record(name)
    config = config_from_record(record["config"])  # every setting a known one, every value accepted
    apply_overrides(spec_for_env(record["env"]), record.get("set", ()))  # eval policy's settings too
    env = make_training_env(config.env, config.overrides, config.grid_input)
    try:
        assert env.observation_space == _model_space(resolve_model(name))
    finally:
        env.close()
    fitted = record["fitted_on"]
    assert "commit" in fitted["code"] and fitted["grid"]


def test_at_most_three_policies_ship_named_for_what_trained_them() -> None:
    names = baseline_names()
    assert 1 <= len(names) <= 3
    for name in names:
        record = baseline_record(name)
        clone = record["steps"] == 0
        assert name.startswith("bc_" if clone else f"{record['algo'].lower()}_"), name


def test_a_renamed_policy_resolves_with_a_warning_and_a_retired_one_is_refused() -> None:
    (old, new), *_ = RENAMED.items()
    with pytest.warns(FutureWarning, match=f"'{old}' is now '{new}'"):
        assert resolve_model(old) == resolve_model(new)
    with pytest.warns(FutureWarning):
        assert baseline_record(old) == baseline_record(new)
    with pytest.warns(FutureWarning):
        assert recorded_env(old) == recorded_env(new)
    assert baseline_record(new)["renamed_from"] == old
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        resolve_model(new)  # the new name is quiet
    for retired in RETIRED:
        assert retired not in baseline_names()
        for lookup in (resolve_model, baseline_record, recorded_env):
            with pytest.raises(ConfigError, match=f"'{retired}' was retired .*bc_offroad_nav_v2_detector"):
                lookup(retired)
