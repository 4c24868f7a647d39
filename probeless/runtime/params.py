"""Node parameters: a frozen dataclass per node, filled from the graph's ``params:`` and checked at load.

Declare fields with :func:`param` to add a range, choices and a doc string::

    @dataclass(frozen=True)
    class Params:
        width: int = param(640, min=1, doc="image width [px]")
        mode: str = param("blur", choices=("blur", "edges"))

Supported types: int, float (ints accepted; floats must be finite), str, bool, ``X | None``,
``Literal[...]`` and ``tuple[X, ...]`` (YAML lists, nested for matrices). An unknown key, a wrong
type or a value out of range raises :class:`ParamError` naming the node id, the key and the YAML line.

Beyond range and choices, :func:`param` declares what a node needs of a value, so ``probeless
check`` reports it before anything starts (a node's ``setup()`` then only uses its params)::

    size: tuple[int, ...] = param((128, 64), length=2, min=1)           # min/max apply to every number
    pose: tuple[float, ...] = param((), length=(0, 7), finite=True)     # empty or 7 numbers
    scene: str = param(path="file", must_exist=True)                   # relative to the working folder
    calib: str = param("", path="file", must_exist=True)               # "" (the default) = not given
    gain: float = param(1.0, min=0, dynamic=True)                      # `probeless param set` changes it live
    ids: tuple[str, ...] = param((), check=unique_ids)                 # check(value) -> error text | None
    pos: tuple[tuple[float, ...], ...] = param((), check=lambda v, p: None if len(v) == len(p.ids)
                                               else "one position per id")   # check(value, params)

A ``check`` taking two arguments gets the whole params object (cross-parameter rules) and runs
once every other check has passed.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
import types
import typing
from pathlib import Path
from typing import Any, Callable, Mapping

from probeless.errors import ParamError

_MISSING = dataclasses.MISSING


PATH_KINDS = ("file", "dir", "any")


def param(default: Any = _MISSING, *, min: float | None = None, max: float | None = None,
          choices: tuple | None = None, doc: str = "", length: int | tuple[int, ...] | None = None,
          min_length: int | None = None, max_length: int | None = None, finite: bool = False,
          path: str | None = None, must_exist: bool = False, resolve: Callable[[str], Any] | None = None,
          check: Callable[..., str | None] | None = None, dynamic: bool = False) -> Any:
    """A parameter field: default, documentation and what a valid value is, all checked at graph load.

    ``min`` / ``max``: inclusive range of a number, or of every number in a list (nested too).
    ``choices``: the allowed values. ``length``: the allowed length(s) of a list or string (an int or
    a tuple of ints); ``min_length`` / ``max_length`` bound it. ``finite``: every number in the value
    (nested lists and mappings too) is finite (float params always are). ``path``: the value is a
    ``"file"``, ``"dir"`` or either (``"any"``); with ``must_exist`` it must exist, a relative path
    resolved against the working folder, as nodes open it (an empty string is "not given" when the
    default is empty); a node that looks elsewhere too passes the same ``resolve(value) -> path`` it
    opens with. ``check``: ``check(value)`` or ``check(value, params)`` returns an error text or
    None; it gets the converted value (tuples, floats) and runs after the other checks of the value.
    ``dynamic``: ``probeless param set`` may change it while the graph runs (checked the same way); the
    node sees the new value in ``self.params`` and, when it defines one, in ``on_param(key, value)``.
    """
    if isinstance(default, list):
        raise TypeError("use a tuple, not a list, as a parameter default")
    if path is not None and path not in PATH_KINDS:
        raise TypeError(f"param(path=...) must be one of {PATH_KINDS}, got {path!r}")
    if must_exist and path is None:
        raise TypeError("param(must_exist=True) needs path='file', 'dir' or 'any'")
    lengths = (length,) if isinstance(length, int) else length
    meta = {"min": min, "max": max, "choices": choices, "doc": doc, "length": lengths, "min_length": min_length,
            "max_length": max_length, "finite": finite, "path": path, "must_exist": must_exist, "resolve": resolve,
            "check": check, "check_params": check is not None and _takes_two_args(check), "dynamic": dynamic}
    return dataclasses.field(default=default, metadata=meta)


def _takes_two_args(fn: Callable) -> bool:
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return False
    positional = [p for p in sig.parameters.values()
                  if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty]
    return len(positional) >= 2 or any(p.kind is p.VAR_POSITIONAL for p in sig.parameters.values())


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
        problem = _type_problem(hints[name], values[name]) or _value_problem(f, _convert(hints[name], values[name]))
        if problem:
            err(name, problem)
    if errors:
        return errors
    # cross-parameter checks: once every value is valid on its own, against the whole params object
    checks = [f for f in fields.values() if f.metadata.get("check_params")]
    if checks:
        params = cls(**{k: _convert(hints[k], v) for k, v in values.items()})
        for f in checks:
            problem = f.metadata["check"](getattr(params, f.name), params)
            if problem:
                err(f.name, problem)
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
    if _matches(hint, value, finite=False):  # right type but for a NaN or infinity
        return f"{_finite_problem(value)} (expected {describe_type(hint)})"
    return f"expected {describe_type(hint)}, got {yaml_kind(value)} {_show_yaml(value)}"


def yaml_kind(value: Any) -> str:
    """What a value is called in YAML terms ('a list', 'a mapping'...), never an internal class name."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, (list, tuple)):
        return "a list"
    return f"a {type(value).__name__}"


def _show_yaml(value: Any) -> str:
    """A value as YAML flow text: [1, 2], {a: 1}, 'text', true, null."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {_show_yaml(v) or 'null'}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_show_yaml(v) or "null" for v in value) + "]"
    return repr(value)


def _first_non_finite(value: Any, where: str = "") -> tuple[str, Any] | None:
    """(position like "[1][2]", number) of the first NaN or infinity in a value, or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return where, value
    items = value.items() if isinstance(value, Mapping) else enumerate(value) \
        if isinstance(value, (list, tuple)) else ()
    for k, v in items:
        found = _first_non_finite(v, f"{where}[{k!r}]" if isinstance(value, Mapping) else f"{where}[{k}]")
        if found:
            return found
    return None


def _matches(hint: Any, value: Any, finite: bool = True) -> bool:
    origin = typing.get_origin(hint)
    if hint is Any:
        return True
    if hint is type(None):
        return value is None
    if origin is typing.Literal:
        return value in typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_matches(a, value, finite) for a in typing.get_args(hint))
    if origin is tuple:
        item = typing.get_args(hint)[0]
        return isinstance(value, (list, tuple)) and all(_matches(item, v, finite) for v in value)
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool) and (math.isfinite(value) or not finite)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint in (str, bool):
        return isinstance(value, hint)
    return False


def _value_problem(f: dataclasses.Field, value: Any) -> str | None:
    """What is wrong with a (type-checked, converted) value by the field's declaration, or None."""
    meta = f.metadata
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        return f"{value!r} is not one of {list(choices)}"
    problem = (_length_problem(meta, value) or _range_problem(meta, value)
               or (_finite_problem(value) if meta.get("finite") else None) or _path_problem(f, value))
    if problem:
        return problem
    check = meta.get("check")
    if check is not None and not meta.get("check_params"):
        return check(value)
    return None


def _length_problem(meta: Mapping[str, Any], value: Any) -> str | None:
    if not isinstance(value, (str, list, tuple)):
        return None
    n, what = len(value), "character(s)" if isinstance(value, str) else "value(s)"
    lengths, lo, hi = meta.get("length"), meta.get("min_length"), meta.get("max_length")
    if lengths is not None and n not in lengths:
        return f"needs {' or '.join(map(str, lengths))} {what}, got {n}: {_show(value)}"
    if lo is not None and n < lo:
        return f"needs at least {lo} {what}, got {n}: {_show(value)}"
    if hi is not None and n > hi:
        return f"needs at most {hi} {what}, got {n}: {_show(value)}"
    return None


def _range_problem(meta: Mapping[str, Any], value: Any, where: str = "") -> str | None:
    """min/max of a number, or of every number in a (nested) list."""
    lo, hi = meta.get("min"), meta.get("max")
    if lo is None and hi is None:
        return None
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            problem = _range_problem(meta, v, f"{where}[{i}]")
            if problem:
                return problem
        return None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        at = f"item {where}: " if where else ""
        if lo is not None and value < lo:
            return f"{at}{value} is below the minimum {lo}"
        if hi is not None and value > hi:
            return f"{at}{value} is above the maximum {hi}"
    return None


def _finite_problem(value: Any) -> str | None:
    found = _first_non_finite(value)
    if found is None:
        return None
    where, bad = found
    return f"{f'item {where}: ' if where else ''}{bad!r} is not finite"


def _path_problem(f: dataclasses.Field, value: Any) -> str | None:
    kind = f.metadata.get("path")
    if kind is None or not f.metadata.get("must_exist") or not isinstance(value, str):
        return None
    if value == "" and f.default == "":
        return None  # the empty default means "not given"
    return path_problem(value, kind, f.metadata.get("resolve"))


def file_load_problem(path: str, load: Callable[[str], Any]) -> str | None:
    """A param check for a file param whose content must load: None for '' (no file) or when ``load(path)``
    succeeds, else the ProbelessError's message (it names the file and the key at fault)."""
    from probeless.errors import ProbelessError

    if not path:
        return None
    try:
        load(path)
    except ProbelessError as exc:
        return str(exc)
    return None


def path_problem(value: str, kind: str = "file", resolve: Callable[[str], Any] | None = None) -> str | None:
    """Why ``value`` is not an existing ``kind`` ("file", "dir" or "any") path, or None.

    A relative path is taken against the working folder, as a node opening it does, unless
    ``resolve`` (the node's own lookup) maps the value to the path the node opens.
    """
    p = Path(resolve(value) if resolve is not None else value)
    ok = {"file": p.is_file, "dir": p.is_dir, "any": p.exists}[kind]()
    if ok:
        return None
    what = {"file": "file not found", "dir": "folder not found", "any": "no such file or folder"}[kind]
    if p.exists():
        what = {"file": "is a folder, not a file", "dir": "is a file, not a folder"}[kind]
    where = "" if p.is_absolute() else f" (relative to the working folder {os.getcwd()})"
    return f"{value}: {what}{where}"


def writable_dir_problem(value: str, name: str | None = None) -> str | None:
    """Why folder ``value`` (created when missing, as output nodes do) cannot be written, or None.

    A param check for output folders (``param(check=writable_dir_problem)``): a part of the path that is
    a file, a read-only file system or a folder without write permission is reported by ``probeless check``.
    """
    if not value:
        return None
    p = Path(value).expanduser()
    probe = p
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    if not probe.is_dir():
        return f"{name or value}: cannot create the folder, {probe} is a file"
    try:
        read_only = bool(os.statvfs(probe).f_flag & os.ST_RDONLY)
    except OSError:
        read_only = False
    if read_only or not os.access(probe, os.W_OK | os.X_OK):
        why = "read-only file system" if read_only else "permission denied"
        return f"{name or value}: cannot write in {probe} ({why})"
    return None


def writable_file_problem(value: str) -> str | None:
    """Why output file ``value`` (its folders created when missing) cannot be written, or None: the check of
    :func:`writable_dir_problem` on its folder."""
    if not value:
        return None
    return writable_dir_problem(str(Path(value).expanduser().parent), name=value)


def _show(value: Any) -> str:
    return repr(list(value)) if isinstance(value, tuple) else repr(value)


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
