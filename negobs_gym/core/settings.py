"""One setting of a nested frozen config dataclass changed by its dotted path: ``fusion.prior=0.4``.

The commands' ``--set KEY.PATH=VALUE``: VALUE is TOML (``true``, ``2.5``, ``[1.0, 2.0]``,
``"text"``), anything else is taken as text. :func:`replace_setting` rebuilds each dataclass on the
path with :func:`dataclasses.replace`, so the config's own checks run on the new value, and takes
the value as the type the setting has now (an int where a float is, a list where a tuple is;
``none`` for an optional setting), so a misspelt key or a value of the wrong kind is a
:class:`ConfigError` naming its full path rather than a failure deep in the code that reads it.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

import tomllib

from negobs_gym.errors import ConfigError

__all__ = ["parse_assignment", "replace_setting"]

OPTION = "--set"  # how errors name the assignment: the option that carried it
Config = TypeVar("Config")


def parse_assignment(
    text: str, example: str = "observation.tighten_pairs=true"
) -> tuple[tuple[str, ...], Any]:
    """``"a.b.c=VALUE"`` -> ``(("a", "b", "c"), value)``; ``example`` shows the form in the error.

    Raises:
        ConfigError: no ``=``, or an empty key in the path.
    """
    path, sep, raw = text.partition("=")
    keys = tuple(k.strip() for k in path.split("."))
    if not sep or not all(keys):
        raise ConfigError(OPTION, f"expected KEY.PATH=VALUE (e.g. {example}), got {text!r}")
    raw = raw.strip()
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return keys, value


def replace_setting(config: Config, keys: tuple[str, ...], value: Any, prefix: str = "") -> Config:
    """``config`` (a frozen dataclass) with the setting at ``keys`` set to ``value``.

    Raises:
        ConfigError: a key the dataclass does not have (the error lists those it has), a path
            through a value, a value of another kind than the setting's, or one the config's own
            checks refuse.
    """
    key, rest = keys[0], keys[1:]
    where = f"{prefix}{key}"
    fields = {f.name: f for f in dataclasses.fields(config)}  # type: ignore[arg-type]
    if key not in fields:
        group = prefix.rstrip(".") or "the config"
        raise ConfigError(OPTION, f"{where}: no such setting; {group} has {', '.join(fields)}")
    current = getattr(config, key)
    if rest:
        if not dataclasses.is_dataclass(current):
            raise ConfigError(OPTION, f"{where}: is a value ({current!r}), not a group of settings")
        new = replace_setting(current, rest, value, f"{where}.")
    elif dataclasses.is_dataclass(current):
        names = ", ".join(f.name for f in dataclasses.fields(current))
        raise ConfigError(OPTION, f"{where}: is a group of settings ({names}); set one of them")
    elif isinstance(value, str) and value.lower() == "none":
        if not str(fields[key].type).endswith("| None"):
            raise ConfigError(OPTION, f"{where}: is not optional (now {current!r})")
        new = None
    elif current is None:
        if not str(fields[key].type).startswith("float"):
            raise ConfigError(OPTION, f"{where}: cannot be set from the command line ({fields[key].type})")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(OPTION, f"{where}: wants a number or none (now none), got {value!r}")
        new = float(value)
    else:
        new = _as_kind_of(current, value, where)
    try:
        return dataclasses.replace(config, **{key: new})  # type: ignore[type-var]
    except (ConfigError, TypeError, ValueError) as error:  # the config's own checks
        raise ConfigError(OPTION, f"{where}={value!r}: {error}") from error


def _as_kind_of(current: Any, value: Any, where: str) -> Any:
    """``value`` as the kind of value ``current`` is."""
    if isinstance(current, bool):
        ok = isinstance(value, bool)
    elif isinstance(current, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(current, float):
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif isinstance(current, tuple):
        ok = isinstance(value, list | tuple)
        if ok and current:
            value = tuple(_as_kind_of(current[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        elif ok:
            value = tuple(value)
    else:
        ok = isinstance(value, type(current))
    if not ok:
        kind = type(current).__name__
        raise ConfigError(OPTION, f"{where}: wants {kind} (now {current!r}), got {value!r}")
    return value
