"""``--set KEY.PATH=VALUE`` on nested frozen config dataclasses (negobs_gym.core.settings)."""

import pytest

from negobs_gym.core.settings import parse_assignment, replace_setting
from negobs_gym.detector import NegativeDetectorConfig, TraversableConfig
from negobs_gym.errors import ConfigError


def test_a_nested_setting_changes_and_nothing_else():
    config = NegativeDetectorConfig()
    keys, value = parse_assignment("fusion.prior=0.4")
    changed = replace_setting(config, keys, value)
    assert changed.fusion.prior == 0.4
    assert (
        changed.fusion.confirm_posterior == config.fusion.confirm_posterior and changed.hdl64 == config.hdl64
    )
    assert config.fusion.prior == 0.5  # frozen: the original stays
    # the kind the setting has now: an int for a float, a list for a tuple, none for an optional
    assert replace_setting(config, ("grid", "ahead_m"), 40).grid.ahead_m == 40.0
    assert isinstance(replace_setting(config, ("grid", "ahead_m"), 40).grid.ahead_m, float)
    assert replace_setting(config, ("hdl64_sensors",), ["top"]).hdl64_sensors == ("top",)
    assert replace_setting(config, ("hdl64", "sensor_height_m"), 2).hdl64.sensor_height_m == 2.0
    taller = replace_setting(config, ("hdl64", "sensor_height_m"), 2.0)
    assert replace_setting(taller, ("hdl64", "sensor_height_m"), "none").hdl64.sensor_height_m is None
    assert replace_setting(TraversableConfig(), ("boundary_layers",), [1, 2, 3]).boundary_layers == (1, 2, 3)


@pytest.mark.parametrize(
    ("keys", "value", "match"),
    [
        (("fusion", "priorx"), 0.4, "fusion.priorx: no such setting; fusion has match_distance_m"),
        (("fusion",), 0.4, "fusion: is a group of settings"),
        (("fusion", "prior", "x"), 0.4, r"fusion.prior: is a value \(0.5\)"),
        (("fusion", "prior"), "high", r"fusion.prior: wants float \(now 0.5\), got 'high'"),
        (("fusion", "prior"), True, "wants float"),
        (("clustering", "min_pairs"), 2.5, "clustering.min_pairs: wants int"),
        (("clustering", "min_pairs"), "none", "is not optional"),
        (("fusion", "prior"), 1.5, r"fusion.prior=1.5: prior: must be in \(0, 1\)"),  # the config's check
        (("hdl64_sensors",), [1], r"hdl64_sensors\[0\]: wants str"),
        (("hdl64", "sensor_height_m"), "tall", r"hdl64.sensor_height_m: wants a number or none \(now none\)"),
        (("fusion", "likelihoods"), 1.0, "fusion.likelihoods: cannot be set from the command line"),
    ],
)
def test_bad_settings_are_refused_by_their_full_path(keys, value, match):
    with pytest.raises(ConfigError, match=match):
        replace_setting(NegativeDetectorConfig(), keys, value)


def test_an_assignment_needs_a_key_and_a_value():
    assert parse_assignment("a.b=[1.0, 2.0]") == (("a", "b"), [1.0, 2.0])
    assert parse_assignment("a=graph") == (("a",), "graph")  # not TOML: text
    for bad in ("a.b", "a..b=1", "=1"):
        with pytest.raises(ConfigError, match=r"expected KEY\.PATH=VALUE"):
            parse_assignment(bad)
