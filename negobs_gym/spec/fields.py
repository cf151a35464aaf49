"""Plain data <-> frozen config dataclasses, with the offending field named in every error.

Scenario specs are read from TOML or dicts and written back with :func:`to_plain`. The converter
walks a dataclass's type hints: nested dataclasses, ``tuple[X, ...]``, fixed tuples, ``Literal``,
``X | None`` and the :class:`Range` of a sampled parameter. Unknown keys, missing required fields
and values of the wrong type are errors (a misspelt option must not be ignored), and a
:class:`~negobs_gym.errors.ConfigError` raised by a config's own ``__post_init__`` is re-raised with
its full path, e.g. ``obstacles[0].depth_m``.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from negobs_gym.errors import ConfigError

__all__ = ["Range", "from_plain", "to_plain"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Range:
    """A parameter sampled uniformly in ``[low, high]`` from the env's generator at each reset.

    Written as ``[low, high]`` in TOML and dicts (``station_m = [12, 20]``).
    """

    low: float
    high: float

    def __post_init__(self) -> None:
        if not (_is_number(self.low) and _is_number(self.high) and self.low <= self.high):
            raise ConfigError(
                "range",
                f"must be [low, high] finite numbers with low <= high, got [{self.low!r}, {self.high!r}]",
            )

    def sample(self, rng: np.random.Generator) -> float:
        """One uniform draw (exactly one number from ``rng``)."""
        return float(rng.uniform(self.low, self.high))


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


class FrozenTable(Mapping[str, Any]):
    """A read-only table of a frozen config (a TOML table such as ``run.driver_settings``).

    Unlike :class:`types.MappingProxyType` it pickles, so a spec travels to worker processes.
    """

    __slots__ = ("_data",)

    def __init__(self, data: Mapping[str, Any] | None = None) -> None:
        self._data = dict(data or {})

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> typing.Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return repr(self._data)

    def __reduce__(self) -> tuple[type, tuple[dict[str, Any]]]:
        return (FrozenTable, (self._data,))


def _convert(hint: Any, value: Any, path: str) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if hint is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in (a for a in args if a is not type(None)):
            try:
                return _convert(arg, value, path)
            except ConfigError as exc:
                errors.append(exc)
        raise errors[-1]
    if origin is Literal:
        if value not in args:
            raise ConfigError(path, f"must be one of {list(args)}, got {value!r}")
        return value
    if hint is Range:
        if isinstance(value, Range):
            return value
        if not (isinstance(value, (list, tuple)) and len(value) == 2 and all(_is_number(v) for v in value)):
            raise ConfigError(path, f"must be a number or a range [low, high], got {value!r}")
        if value[0] > value[1]:
            raise ConfigError(path, f"range [low, high] needs low <= high, got {list(value)}")
        return Range(low=float(value[0]), high=float(value[1]))
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(path, f"must be a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{path}[{k}]") for k, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(path, f"must have {len(args)} items, got {len(value)}")
        return tuple(_convert(a, v, f"{path}[{k}]") for k, (a, v) in enumerate(zip(args, value, strict=True)))
    if origin in (dict, Mapping) or hint in (dict, Mapping):
        if not isinstance(value, Mapping):
            raise ConfigError(path, f"must be a table, got {value!r}")
        return FrozenTable(value)
    if dataclasses.is_dataclass(hint):
        if isinstance(value, hint):
            return value
        return from_plain(hint, value, path)
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(path, f"must be true or false, got {value!r}")
        return value
    if hint is float:
        if not _is_number(value):
            raise ConfigError(path, f"must be a finite number, got {value!r}")
        return float(value)
    if hint is int:
        if not (isinstance(value, int) and not isinstance(value, bool)):
            raise ConfigError(path, f"must be an integer, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(path, f"must be a string, got {value!r}")
        return value
    raise TypeError(f"{path}: no converter for type {hint!r}")  # a bug in a spec class, not user input


def _required(field: dataclasses.Field) -> bool:
    return field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING


def from_plain(cls: type, data: Any, path: str = "") -> Any:
    """Build dataclass ``cls`` from a mapping; every error names the field by its full path.

    Raises:
        ConfigError: ``data`` is no mapping, has an unknown key, lacks a required field, or holds
            a value of the wrong type or a value the config's own checks refuse.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(path or cls.__name__, f"must be a table of {cls.__name__} fields, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(_join(path, str(unknown[0])), f"unknown key; {cls.__name__} has {sorted(fields)}")
    missing = [name for name, f in fields.items() if _required(f) and name not in data]
    if missing:
        required = [name for name, f in fields.items() if _required(f)]
        raise ConfigError(_join(path, missing[0]), f"missing; a {cls.__name__} needs {required}")
    kwargs = {name: _convert(hints[name], value, _join(path, name)) for name, value in data.items()}
    try:
        return cls(**kwargs)
    except ConfigError as exc:  # the config's own check names its field; add where the config sits
        if not path:
            raise
        raise ConfigError(_join(path, exc.field), str(exc)[len(exc.field) + 2 :]) from None


def to_plain(obj: Any) -> Any:
    """Dataclasses, ranges and tuples as TOML-ready dicts and lists; ``None`` fields are left out."""
    if isinstance(obj, Range):
        return [obj.low, obj.high]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {}
        for f in dataclasses.fields(obj):
            if not f.init:
                continue
            value = getattr(obj, f.name)
            if value is not None:
                out[f.name] = to_plain(value)
        return out
    if isinstance(obj, Mapping):
        return {str(k): to_plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    return obj
