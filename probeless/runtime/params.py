"""Node parameters: a frozen dataclass per node, filled from the graph's ``params:`` and checked at load.

Declare fields with :func:`param` to add a range, choices and a doc string::

    @dataclass(frozen=True)
    class Params:
        width: int = param(640, min=1, doc="image width [px]")
        mode: str = param("blur", choices=("blur", "edges"))

Supported types: int, float (ints accepted), str, bool, ``X | None``, ``Literal[...]`` and
``tuple[X, ...]`` (YAML lists, nested for matrices). An unknown key, a wrong type or a value out
of range raises :class:`ParamError` naming the node id, the key and the YAML line.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from typing import Any, Mapping

from probeless.errors import ParamError

_MISSING = dataclasses.MISSING


def param(default: Any = _MISSING, *, min: float | None = None, max: float | None = None,
          choices: tuple | None = None, doc: str = "") -> Any:
    """A parameter field with optional inclusive range, allowed choices and documentation."""
    meta = {"min": min, "max": max, "choices": choices, "doc": doc}
    if isinstance(default, list):
        raise TypeError("use a tuple, not a list, as a parameter default")
    return dataclasses.field(default=default, metadata=meta)


def load_params(cls: type, values: Mapping[str, Any] | None, *, node_id: str, file: str | None = None,
                lines: Mapping[str, int] | None = None, line: int | None = None) -> Any:
    """Build ``cls`` from a mapping, raising ParamError (the first) or returning the instance."""
    errors = check_params(cls, values, node_id=node_id, file=file, lines=lines, line=line)
    if errors:
        raise errors[0]
    kwargs = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if values and f.name in values:
            kwargs[f.name] = _convert(hints[f.name], values[f.name])
    return cls(**kwargs)


def check_params(cls: type, values: Mapping[str, Any] | None, *, node_id: str, file: str | None = None,
                 lines: Mapping[str, int] | None = None, line: int | None = None) -> list[ParamError]:
    """All parameter errors of ``values`` against ``cls`` (empty list when valid)."""
    values = values or {}
    lines = lines or {}
    if not isinstance(values, Mapping):
        return [ParamError("params must be a mapping", file=file, line=line, node_id=node_id, key="params")]
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    errors = []

    def err(key: str, msg: str) -> None:
        errors.append(ParamError(msg, file=file, line=lines.get(key, line), node_id=node_id, key=key))

    for key in values:
        if key not in fields:
            known = ", ".join(sorted(fields)) or "none"
            err(key, f"unknown parameter (known: {known})")
    for name, f in fields.items():
        if name not in values:
            if f.default is _MISSING and f.default_factory is _MISSING:
                err(name, "required parameter is missing")
            continue
        problem = _type_problem(hints[name], values[name]) or _range_problem(f.metadata, values[name])
        if problem:
            err(name, problem)
    return errors


def describe_type(hint: Any) -> str:
    """Short human-readable name of a parameter type."""
    origin = typing.get_origin(hint)
    if origin is typing.Literal:
        return " | ".join(repr(a) for a in typing.get_args(hint))
    if origin in (typing.Union, types.UnionType):
        return " | ".join(describe_type(a) for a in typing.get_args(hint))
    if origin is tuple:
        return f"list of {describe_type(typing.get_args(hint)[0])}"
    return getattr(hint, "__name__", str(hint))


def _type_problem(hint: Any, value: Any) -> str | None:
    if _matches(hint, value):
        return None
    return f"expected {describe_type(hint)}, got {type(value).__name__} {value!r}"


def _matches(hint: Any, value: Any) -> bool:
    origin = typing.get_origin(hint)
    if hint is Any:
        return True
    if hint is type(None):
        return value is None
    if origin is typing.Literal:
        return value in typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_matches(a, value) for a in typing.get_args(hint))
    if origin is tuple:
        item = typing.get_args(hint)[0]
        return isinstance(value, (list, tuple)) and all(_matches(item, v) for v in value)
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint in (str, bool):
        return isinstance(value, hint)
    return False


def _range_problem(meta: Mapping[str, Any], value: Any) -> str | None:
    lo, hi, choices = meta.get("min"), meta.get("max"), meta.get("choices")
    if choices is not None and value not in choices:
        return f"{value!r} is not one of {list(choices)}"
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if lo is not None and value < lo:
            return f"{value} is below the minimum {lo}"
        if hi is not None and value > hi:
            return f"{value} is above the maximum {hi}"
    return None


def _convert(hint: Any, value: Any) -> Any:
    origin = typing.get_origin(hint)
    if origin is tuple and isinstance(value, (list, tuple)):
        item = typing.get_args(hint)[0]
        return tuple(_convert(item, v) for v in value)
    if origin in (typing.Union, types.UnionType):
        for arg in typing.get_args(hint):
            if _matches(arg, value):
                return _convert(arg, value)
    if hint is float and isinstance(value, int):
        return float(value)
    return value


def params_doc(cls: type) -> list[tuple[str, str, Any, str]]:
    """(name, type, default, doc) for every parameter, for help texts."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        default = None if f.default is _MISSING else f.default
        out.append((f.name, describe_type(hints[f.name]), default, f.metadata.get("doc", "")))
    return out
