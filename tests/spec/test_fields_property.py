"""A spec with a required field removed or a field of the wrong type, from a dict or from TOML, is a
ConfigError naming the field's full path, and ``negobs scenario show FILE`` says so in one line."""

from __future__ import annotations

import copy
import dataclasses
import types
import typing
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, Literal

import pytest
import tomllib
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from negobs_gym.cli import main
from negobs_gym.errors import ConfigError
from negobs_gym.spec import Range, ScenarioSpec, load_scenario, scenario_names, spec_from_toml
from negobs_gym.spec.toml_out import dumps_toml

#: A value of each TOML kind, given to a field that takes no value of that kind.
WRONG: dict[str, Any] = {
    "bool": True,
    "int": 7,
    "float": 2.5,
    "str": "wrong",
    "array": [1, 2],
    "table": {"wrong": 1},
}


def _kinds(hint: Any) -> set[str]:
    """The TOML kinds a field of type ``hint`` takes (a float field takes ints too)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any:
        return set(WRONG)
    if origin in (typing.Union, types.UnionType):
        return set().union(*(_kinds(a) for a in args if a is not type(None)))
    if origin is Literal:
        return set().union(*(_kinds(type(a)) for a in args))
    if hint is Range or origin is tuple:
        return {"array"}
    if dataclasses.is_dataclass(hint) or Mapping in (hint, origin) or dict in (hint, origin):
        return {"table"}
    simple = {bool: {"bool"}, int: {"int"}, float: {"int", "float"}, str: {"str"}}
    return simple[hint]


def _dataclass_of(hint: Any) -> type | None:
    """The dataclass a field holds (itself or optional), else None."""
    candidates = (
        typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    )
    return next((c for c in candidates if dataclasses.is_dataclass(c)), None)


def _fields(cls: type, data: Mapping[str, Any], path: str = "") -> Iterator[tuple[str, Any, bool]]:
    """(full path, type hint, required) of every field present in ``data``, nested ones included."""
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        if not field.init or field.name not in data:
            continue
        where = f"{path}.{field.name}" if path else field.name
        hint, value = hints[field.name], data[field.name]
        required = field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING
        yield where, hint, required
        inner = _dataclass_of(hint)
        if inner is not None and isinstance(value, Mapping):
            yield from _fields(inner, value, where)
        item_hint = typing.get_args(hint)[0] if typing.get_origin(hint) is tuple else None
        if dataclasses.is_dataclass(item_hint) and isinstance(value, list):
            for k, item in enumerate(value):
                yield from _fields(item_hint, item, f"{where}[{k}]")


def _cases() -> list[tuple[str, str, str | None]]:
    """(scene, field path, wrong kind): a kind the field does not take, or None to remove it."""
    cases = []
    for scene in scenario_names():
        for path, hint, required in _fields(ScenarioSpec, load_scenario(scene).to_dict()):
            if required:
                cases.append((scene, path, None))
            cases.extend((scene, path, kind) for kind in sorted(set(WRONG) - _kinds(hint)))
    return cases


SCENES = {name: load_scenario(name).to_dict() for name in scenario_names()}
CASES = _cases()
REMOVED = [case for case in CASES if case[2] is None]
#: Each (path, kind) once, in the first scene that has the path (the shipped scenes share most).
DISTINCT = list({(path, kind): (scene, path, kind) for scene, path, kind in reversed(CASES)}.values())
#: Removals are ~0.5 % of the cases: drawn as often as wrong types.
ANY_CASE = st.one_of(st.sampled_from(REMOVED), st.sampled_from([c for c in CASES if c[2] is not None]))


def _steps(path: str) -> list[str | int]:
    """``obstacles[0].station_m`` -> ``["obstacles", 0, "station_m"]``."""
    steps: list[str | int] = []
    for part in path.split("."):
        name, *indices = part.replace("]", "").split("[")
        steps.append(name)
        steps.extend(int(i) for i in indices)
    return steps


def _broken(scene: str, path: str, kind: str | None) -> dict[str, Any]:
    """The scene's plain data with the field at ``path`` removed (kind None) or of the wrong kind."""
    data = copy.deepcopy(SCENES[scene])
    *parents, last = _steps(path)
    holder: Any = data
    for step in parents:
        holder = holder[step]
    if kind is None:
        del holder[last]
    else:
        holder[last] = copy.deepcopy(WRONG[kind])
    return data


def _toml(data: dict[str, Any]) -> str:
    text = dumps_toml(data)
    assert tomllib.loads(text) == data  # the TOML case holds the same broken data as the dict case
    return text


def test_the_cases_cover_required_fields_and_every_kind() -> None:
    removed = {path for _, path, kind in CASES if kind is None}
    assert {"name", "terrain", "obstacles[0].station_m", "positive_obstacles[0].station_m"} <= removed
    assert {kind for _, _, kind in CASES} == {*WRONG, None}
    assert len({scene for scene, _, _ in CASES}) == len(SCENES)


@pytest.mark.parametrize("path", ["terrain", "obstacles[0].station_m"])
def test_the_issues_two_examples_name_their_field(path: str) -> None:
    data = _broken("paper_n_grass_pit", path, None)
    for build in (ScenarioSpec.from_dict, lambda d: spec_from_toml(_toml(d))):
        with pytest.raises(ConfigError, match=r"missing; a \w+ needs") as error:
            build(data)
        assert error.value.field == path


def _refusal(case: tuple[str, str, str | None], from_toml: bool) -> ConfigError:
    """The ConfigError that reading the broken scene raises."""
    scene, path, kind = case
    data = _broken(scene, path, kind)
    with pytest.raises(ConfigError) as error:
        spec_from_toml(_toml(data)) if from_toml else ScenarioSpec.from_dict(data)
    return error.value


def _names_its_path(case: tuple[str, str, str | None], error: ConfigError) -> bool:
    path = case[1]
    return error.field == path and str(error).startswith(f"{path}: ")


def test_every_field_removed_or_wrongly_typed_once_from_a_dict() -> None:
    assert len(DISTINCT) > 500  # every field path of the shipped scenes, each wrong kind
    for case in DISTINCT:
        assert _names_its_path(case, _refusal(case, from_toml=False)), case


@settings(max_examples=100, deadline=None)
@given(case=ANY_CASE, from_toml=st.booleans())
def test_a_removed_or_wrongly_typed_field_of_any_scene_is_a_config_error_naming_its_path(
    case: tuple[str, str, str | None], from_toml: bool
) -> None:
    assert _names_its_path(case, _refusal(case, from_toml)), case


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=ANY_CASE)
def test_negobs_scenario_show_prints_the_field_in_one_line_and_exits_2(
    case: tuple[str, str, str | None], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene, path, kind = case
    spec_file = tmp_path / "broken.toml"
    spec_file.write_text(_toml(_broken(scene, path, kind)), encoding="utf-8")
    capsys.readouterr()  # the output of earlier examples
    assert main(["scenario", "show", str(spec_file)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # no spec printed
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"negobs scenario: {path}: ")
