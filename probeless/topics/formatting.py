"""Printing messages: YAML-like lines, arrays summarized by dtype, shape and statistics."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from probeless.messages.base import Struct, schema_of


def summarize_array(a: np.ndarray, stats: bool = True) -> str:
    """``ndarray uint8 (480, 640, 3) min 0 max 255``; floats add the mean; empty arrays say so."""
    text = f"ndarray {a.dtype.name} {tuple(a.shape)}"
    if not stats:
        return text
    if a.size == 0:
        return f"{text} empty"
    kind = a.dtype.kind
    if kind == "b":
        return f"{text} true {int(np.count_nonzero(a))} of {a.size}"
    if kind == "c":
        return f"{text} mean {complex(a.mean(dtype=np.complex128)):.6g} max |x| {float(np.abs(a).max()):.6g}"
    if kind == "f":
        finite = a[np.isfinite(a)].astype(np.float64)
        bad = a.size - finite.size
        if finite.size == 0:
            return f"{text} no finite values ({bad} nan/inf)"
        text += f" min {finite.min():.6g} max {finite.max():.6g} mean {finite.mean():.6g}"
        return text + (f" nan/inf {bad}" if bad else "")
    return f"{text} min {a.min()} max {a.max()}"


_PLAIN = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_./-+=@")
MAX_INLINE_ITEMS = 32


def _scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else {"inf": ".inf", "-inf": "-.inf"}.get(repr(v), ".nan")
    if isinstance(v, str):
        plain = v and set(v) <= _PLAIN and v not in ("true", "false", "null", "~") and not _looks_numeric(v)
        return v if plain else json.dumps(v)
    return str(v)


def _looks_numeric(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def format_message(msg: Struct, *, arrays: bool = True, indent: str = "") -> list[str]:
    """YAML-like lines for a message or struct: scalars, nested structs, tuples, array summaries."""
    lines = []
    for spec in schema_of(type(msg)):
        lines += _format_field(spec.name, getattr(msg, spec.name), arrays, indent)
    return lines


def _format_field(name: str, value: Any, arrays: bool, indent: str) -> list[str]:
    if isinstance(value, np.ndarray):
        return [f"{indent}{name}: {summarize_array(value, arrays)}"]
    if isinstance(value, Struct):
        return [f"{indent}{name}:", *format_message(value, arrays=arrays, indent=indent + "  ")]
    if isinstance(value, tuple):
        if not value:
            return [f"{indent}{name}: []"]
        if not any(isinstance(v, (Struct, np.ndarray)) for v in value):
            shown = ", ".join(_scalar(v) for v in value[:MAX_INLINE_ITEMS])
            more = f", ... ({len(value) - MAX_INLINE_ITEMS} more)" if len(value) > MAX_INLINE_ITEMS else ""
            return [f"{indent}{name}: [{shown}{more}]"]
        lines = [f"{indent}{name}:"]
        for v in value:
            if isinstance(v, Struct):
                sub = format_message(v, arrays=arrays, indent=indent + "    ")
                lines += [f"{indent}  - {sub[0].lstrip()}", *sub[1:]] if sub else [f"{indent}  - {{}}"]
            else:
                lines.append(f"{indent}  - {summarize_array(v, arrays)}")
        return lines
    return [f"{indent}{name}: {_scalar(value)}"]
