"""Strict readers for scene-file values: every error names the file, the line and the key path."""

from __future__ import annotations

import math
from typing import Any, Iterable

import numpy as np

from probeless.errors import SceneError


class Where:
    """A position in the scene file: file name, key path and YAML line, for error messages."""

    def __init__(self, file: str, path: str = "", line: int = 0):
        self.file, self.path, self.line = file, path, line

    def child(self, key: str | int, container: Any = None) -> "Where":
        line = self.line
        if isinstance(key, str) and hasattr(container, "line_of"):
            line = container.line_of(key)
        elif isinstance(key, int) and hasattr(container, "lines") and key < len(container.lines):
            line = container.lines[key]
        sep = "" if not self.path else "."
        name = f"[{key}]" if isinstance(key, int) else f"{sep}{key}"
        return Where(self.file, f"{self.path}{name}", line)

    def error(self, message: str) -> SceneError:
        at = f"{self.file}:{self.line}" if self.line else self.file
        return SceneError(f"{at}: {self.path or '<top>'}: {message}")


def mapping(value: Any, where: Where, required: Iterable[str], optional: Iterable[str] = ()) -> dict:
    """Check ``value`` is a mapping with all ``required`` keys and nothing unknown."""
    if not isinstance(value, dict):
        raise where.error(f"expected a mapping, got {type(value).__name__}")
    required, optional = list(required), list(optional)
    for key in value:
        if key not in required and key not in optional:
            raise where.child(str(key), value).error(f"unknown key (allowed: {', '.join(required + optional)})")
    for key in required:
        if key not in value:
            raise where.error(f"missing key {key!r}")
    return value


def number(value: Any, where: Where, *, min: float | None = None, max: float | None = None,
           strict_min: bool = False) -> float:
    """A finite real number within [min, max] (or (min, max] with ``strict_min``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise where.error(f"expected a finite number, got {value!r}")
    if min is not None and (value < min or (strict_min and value <= min)):
        raise where.error(f"must be {'>' if strict_min else '>='} {min}, got {value}")
    if max is not None and value > max:
        raise where.error(f"must be <= {max}, got {value}")
    return float(value)


def integer(value: Any, where: Where, *, min: int | None = None, max: int | None = None) -> int:
    """An integer within [min, max]."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise where.error(f"expected an integer, got {value!r}")
    number(value, where, min=min, max=max)
    return int(value)


def vector(value: Any, where: Where, n: int, *, min: float | None = None, strict_min: bool = False) -> np.ndarray:
    """A list of ``n`` finite numbers as float64."""
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise where.error(f"expected a list of {n} numbers, got {value!r}")
    return np.array([number(v, where.child(i, value), min=min, strict_min=strict_min) for i, v in enumerate(value)])


def string(value: Any, where: Where, choices: Iterable[str] | None = None) -> str:
    """A non-empty string, optionally one of ``choices``."""
    if not isinstance(value, str) or not value:
        raise where.error(f"expected a non-empty string, got {value!r}")
    if choices is not None and value not in choices:
        raise where.error(f"{value!r} is not one of {', '.join(choices)}")
    return value


def boolean(value: Any, where: Where) -> bool:
    """true or false."""
    if not isinstance(value, bool):
        raise where.error(f"expected true or false, got {value!r}")
    return value


def sequence(value: Any, where: Where, *, min_len: int = 0) -> list:
    """A YAML list with at least ``min_len`` items."""
    if not isinstance(value, list):
        raise where.error(f"expected a list, got {type(value).__name__}")
    if len(value) < min_len:
        raise where.error(f"expected at least {min_len} item(s), got {len(value)}")
    return value
