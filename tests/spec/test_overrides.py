"""``--set KEY.PATH=VALUE``: single settings of a scenario changed without a copied TOML file."""

from __future__ import annotations

import pytest

import negobs_gym  # noqa: F401  (registers the envs)
from negobs_gym.errors import ConfigError
from negobs_gym.spec import load_scenario
from negobs_gym.spec.overrides import (
    apply_overrides,
    combine_overrides,
    parse_assignment,
    spec_for_env,
)


@pytest.mark.parametrize(
    ("text", "keys", "value"),
    [
        ("observation.tighten_pairs=true", ("observation", "tighten_pairs"), True),
        ("episode.time_limit_s = 30", ("episode", "time_limit_s"), 30),
        ("observation.route_points_m=[5.0, 10.0]", ("observation", "route_points_m"), [5.0, 10.0]),
        ('run.driver="reckless"', ("run", "driver"), "reckless"),
        ("run.driver=reckless", ("run", "driver"), "reckless"),  # not TOML: taken as text
    ],
)
def test_parse_reads_toml_values_and_falls_back_to_text(text: str, keys: tuple, value: object) -> None:
    assert parse_assignment(text) == (keys, value)


def test_overrides_change_only_the_named_settings() -> None:
    spec = load_scenario("paper_n_three_pits")
    changed = apply_overrides(
        spec, ["observation.tighten_pairs=false", "obstacles.0.depth_m=1.2", "observation.grid.cell_m=0.4"]
    )
    assert changed.observation.tighten_pairs is False and spec.observation.tighten_pairs is True
    assert changed.obstacles[0].depth_m == 1.2 and spec.obstacles[0].depth_m == 0.8
    assert changed.observation.grid.cell_m == 0.4
    same = {k: v for k, v in changed.to_dict().items() if k not in ("observation", "obstacles")}
    assert same == {k: v for k, v in spec.to_dict().items() if k not in ("observation", "obstacles")}
    assert changed.obstacles[1:] == spec.obstacles[1:]
    assert apply_overrides(spec, []) == spec


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("observation.tighten_pairs", r"--set: expected KEY.PATH=VALUE"),
        ("observation..rig=roi", r"--set: expected KEY.PATH=VALUE"),
        ("observation.tighten=true", r"observation.tighten: unknown key"),
        ("observation.tighten_pairs=yes", r"observation.tighten_pairs: must be true or false"),
        ("name.first=x", r"--set: name.first: name is a value, not a table"),
        ("obstacles.7.depth_m=1", r"--set: obstacles.7: the list has 3 elements, index 0-2"),
        ("obstacles.0.depth_m=-1", r"obstacles\[0\].depth_m"),
    ],
)
def test_bad_overrides_name_the_field(text: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        apply_overrides(load_scenario("paper_n_three_pits"), [text])


def test_an_index_into_an_empty_list_says_so() -> None:
    with pytest.raises(ConfigError, match=r"--set: obstacles\.0: the list is empty"):
        apply_overrides(load_scenario("offroad_nav_v2"), ["obstacles.0.depth_m=1"])


def test_an_env_id_resolves_to_its_scenario() -> None:
    assert spec_for_env("negobs_gym/OffroadTrack-v0") == load_scenario("offroad_nav_v2")
    assert spec_for_env("negobs_gym/OffroadNav-v2") == load_scenario("offroad_nav_v2")  # its old id, an alias
    assert spec_for_env("paper_n_mud_pit") == load_scenario("paper_n_mud_pit")
    with pytest.raises(ConfigError, match="unknown scenario 'CartPole-v1'"):  # no negobs env, no scene
        spec_for_env("CartPole-v1")
    with pytest.raises(ConfigError, match="unknown scenario"):
        spec_for_env("no_such_scene")


def test_combined_overrides_let_the_later_assignment_to_a_key_replace_the_earlier() -> None:
    record = ["observation.tighten_pairs=false", "observation.hazard_hold_s=2.0"]
    combined = combine_overrides(record, ["observation.tighten_pairs = true", "episode.time_limit_s=9"])
    assert combined == [
        "observation.hazard_hold_s=2.0",
        "observation.tighten_pairs = true",
        "episode.time_limit_s=9",
    ]
    spec = apply_overrides(load_scenario("offroad_nav_v2_structure"), combined)
    assert spec.observation.tighten_pairs is True and spec.observation.hazard_hold_s == 2.0
    assert spec.episode.time_limit_s == 9
    assert combine_overrides(record, []) == record
    with pytest.raises(ConfigError, match=r"KEY\.PATH=VALUE"):
        combine_overrides(record, ["tighten"])


def test_an_overridden_spec_pickles_with_its_tables_read_only() -> None:
    """Worker processes receive the spec pickled: its tables (``run.driver_settings``) must pickle
    after ``--set`` rebuilt them, and stay read-only."""
    import pickle

    spec = apply_overrides(
        load_scenario("braking_v0"),
        ["filter.steer_search=0.3", "run.driver_settings.planner.bend_steps=1"],
    )
    again = pickle.loads(pickle.dumps(spec))
    assert again == spec and again.run.driver_settings == {"planner": {"bend_steps": 1}}
    with pytest.raises(TypeError):
        spec.run.driver_settings["planner"] = {}  # type: ignore[index]
