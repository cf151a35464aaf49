"""Single settings of a scenario changed from the command line: ``--set observation.tighten_pairs=true``.

An ablation should not need a copied TOML file per setting. An assignment is ``KEY.PATH=VALUE``:
the path walks the spec's tables as :meth:`ScenarioSpec.to_dict` spells them (a list element by
its index, ``obstacles.0.depth_m``), and VALUE is TOML (``true``, ``2.5``, ``[1.0, 2.0]``,
``"text"``); a VALUE that is not TOML is taken as text (``run.driver=reckless``). The changed spec
is validated as a whole, so a misspelt key or a bad value is a :class:`ConfigError` naming its
full path, as in a TOML file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeAlias

from negobs_gym.core.files import write_text_atomic
from negobs_gym.core.settings import parse_assignment
from negobs_gym.errors import ConfigError
from negobs_gym.registration import SCENES
from negobs_gym.spec.library import load_scenario
from negobs_gym.spec.scenario import ScenarioSpec, spec_to_toml

__all__ = [
    "Overrides",
    "apply_overrides",
    "combine_overrides",
    "describe_overrides",
    "env_with_overrides",
    "parse_assignment",
    "recorded_env_in",
    "spec_for_env",
]

OPTION = "--set"  # how errors name the assignment: the option that carried it

#: Settings changed on a spec: ``"KEY.PATH=VALUE"`` texts (the commands' ``--set``), or a mapping
#: from ``KEY.PATH`` to a plain value (``{"observation.source": "oracle"}``).
Overrides: TypeAlias = Sequence[str] | Mapping[str, Any]


def _assignments(overrides: Overrides) -> list[tuple[list[str], Any]]:
    """``(keys, value)`` of each override, in order."""
    if isinstance(overrides, Mapping):
        pairs = []
        for key, value in overrides.items():
            keys = str(key).split(".")
            if not all(keys):
                raise ConfigError(OPTION, f"{key!r}: a key is KEY.PATH, dot-separated names")
            pairs.append((keys, value))
        return pairs
    if isinstance(overrides, str):
        raise ConfigError(OPTION, f"give a list of KEY.PATH=VALUE assignments, not one string {overrides!r}")
    return [parse_assignment(text) for text in overrides]


def apply_overrides(spec: ScenarioSpec, assignments: Overrides) -> ScenarioSpec:
    """``spec`` with each assignment applied in order, validated as one new spec (``spec``
    itself when there are none).

    Raises:
        ConfigError: a malformed assignment, a path through a value or past a list's end, or a
            changed spec that does not validate (the error names the field's full path).
    """
    changes = _assignments(assignments)
    if not changes:
        return spec
    data = spec.to_dict()
    for keys, value in changes:
        node: Any = data
        for depth, key in enumerate(keys):
            where = ".".join(keys[: depth + 1])
            last = depth == len(keys) - 1
            if isinstance(node, list):
                if not key.isdigit() or int(key) >= len(node):
                    size = f"has {len(node)} elements, index 0-{len(node) - 1}" if node else "is empty"
                    raise ConfigError(OPTION, f"{where}: the list {size}")
                if last:
                    node[int(key)] = value
                else:
                    node = node[int(key)]
            elif isinstance(node, dict):
                if last:
                    node[key] = value
                else:
                    node = node.setdefault(key, {})
            else:
                raise ConfigError(OPTION, f"{where}: {'.'.join(keys[:depth])} is a value, not a table")
    return ScenarioSpec.from_dict(data)


def combine_overrides(first: Sequence[str], then: Sequence[str]) -> list[str]:
    """``first`` followed by ``then``, where an assignment in ``then`` to a key ``first`` also
    sets replaces that one: a policy record's settings, then the command's own, as one list
    that says once what runs (``observation.tighten_pairs=true`` over the record's ``false``).

    Raises:
        ConfigError: a malformed assignment (:func:`parse_assignment`).
    """
    overridden = {parse_assignment(text)[0] for text in then}
    return [text for text in first if parse_assignment(text)[0] not in overridden] + list(then)


def spec_for_env(env: str) -> ScenarioSpec:
    """The scenario spec behind an env argument: a registered negobs env id (the scene it runs,
    :data:`negobs_gym.registration.SCENES`), a shipped scenario name or a scenario TOML file.

    Raises:
        ConfigError: an unknown id, scenario or file (field ``scenario``).
    """
    return load_scenario(SCENES.get(env, env))


def env_with_overrides(
    env: str, overrides: Sequence[str], out_dir: str | Path, *, replace: bool = False
) -> str:
    """``env`` itself without assignments; otherwise its scenario with them applied, written to
    ``out_dir/scenario.toml`` (atomically; it records what ran), whose path runs in its place.

    Raises:
        ConfigError: a bad assignment (:func:`apply_overrides`), or ``out_dir/scenario.toml``
            holds another scenario (an earlier run's, which a resumed run would go on with) and
            ``replace`` is false.
    """
    if not overrides:
        return env
    text = spec_to_toml(apply_overrides(spec_for_env(env), overrides))
    path = Path(out_dir) / "scenario.toml"
    if path.is_file() and path.read_text(encoding="utf-8") != text and not replace:
        raise ConfigError(
            OPTION, f"{path} holds an earlier run's other scenario: use its settings or another --out"
        )
    write_text_atomic(path, text)
    return str(path)


def recorded_env_in(env: str, run_dir: str | Path) -> str:
    """The env a run recorded, as it can be found now: a ``--set`` run records the
    ``scenario.toml`` it wrote by the path it ran with (relative to where it ran), so when that
    path is gone the file of that name in ``run_dir`` is the one."""
    beside = Path(run_dir) / Path(env).name
    if env.endswith(".toml") and not Path(env).is_file() and beside.is_file():
        return str(beside)
    return env


def describe_overrides(env: str, overrides: Sequence[str]) -> str:
    """A one-word label of ``env`` with its assignments, for result lines and logs:
    ``negobs_gym/OffroadTrack-v0[observation.tighten_pairs=true]``."""
    return f"{env}[{','.join(overrides)}]" if overrides else env
