"""A small TOML writer for plain data (the stdlib reads TOML, ``tomllib``, but does not write it).

Covers what :func:`negobs_gym.spec.fields.to_plain` produces: nested tables, strings, bools,
ints, floats and lists; lists of tables are written as arrays of inline tables.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

__all__ = ["dumps_toml"]

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped, the rest verbatim."""
    out = []
    for ch in text:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _key(name: str) -> str:
    return name if _BARE_KEY.match(name) else _string(name)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(  # a bug, not user input: a validated spec's plain data holds TOML types only
        f"cannot write {type(value).__name__} as TOML: {value!r}"
    )


def _table(data: Mapping[str, Any], prefix: str, out: list[str]) -> None:
    tables = {k: v for k, v in data.items() if isinstance(v, Mapping)}
    for key, value in data.items():
        if key not in tables:
            out.append(f"{_key(key)} = {_value(value)}")
    for key, value in tables.items():
        name = f"{prefix}.{_key(key)}" if prefix else _key(key)
        out.append("")
        out.append(f"[{name}]")
        _table(value, name, out)


def dumps_toml(data: Mapping[str, Any]) -> str:
    """``data`` (str keys; tables, lists and scalars) as a TOML document."""
    out: list[str] = []
    _table(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"
