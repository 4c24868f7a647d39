"""Launch-file arguments and substitutions: ``$(arg NAME)``, ``$(env NAME [default])``, ``$(dirname)``."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from probeless.launch.yamlload import LineDict, LineList

_SUBST = re.compile(r"\$\((arg|env|dirname)(?:\s+([^)\s]+))?(?:\s+([^)]*))?\)")
_NOT_GIVEN = object()  # a required argument that was not passed (reported once, not at every use)


def resolve_args(decl: Any, overrides: dict, err, line: int, is_root: bool) -> dict:
    """Argument values: CLI/include overrides, else defaults; reports missing and unknown arguments."""
    decl = decl or {}
    if not isinstance(decl, dict):
        err("'args' must be a mapping of name: default", line, key="args")
        return {}
    out = {}
    for name, spec in decl.items():
        default = spec.get("default") if isinstance(spec, dict) else spec
        required = isinstance(spec, dict) and "default" not in spec
        if name in overrides:
            out[name] = overrides[name]
        elif required:
            err("required argument not given (pass name:=value)", decl.line_of(name), key=f"args.{name}")
            out[name] = _NOT_GIVEN
        else:
            out[name] = default
    for name in overrides:
        if name not in decl and is_root:
            err(f"unknown argument {name!r} (declared: {', '.join(map(str, decl)) or 'none'})", line, key=name)
    return out


_INT = re.compile(r"-?(0|[1-9][0-9]*)")
_FLOAT = re.compile(r"-?([0-9]+\.[0-9]*|\.[0-9]+|[0-9]+(\.[0-9]*)?[eE][-+]?[0-9]+)")


def env_scalar(text: str) -> Any:
    """An environment value standing alone as a param: a plain decimal number or true/false becomes one
    (``linger_s: $(env LINGER 5.0)``); anything else, leading zeros included, stays the string it is."""
    if _INT.fullmatch(text):
        return int(text)
    if _FLOAT.fullmatch(text):
        return float(text)
    return {"true": True, "false": False}.get(text, text)


class Substituter:
    """Applies $(arg)/$(env)/$(dirname) to every string in a value."""

    def __init__(self, args: dict, dirname: Path, err):
        self.args, self.dirname, self.err = args, dirname, err

    def __call__(self, value: Any, line: int) -> Any:
        if isinstance(value, str):
            return self._string(value, line)
        if isinstance(value, LineDict):
            out = LineDict((k, self(v, value.line_of(k))) for k, v in value.items())
            out.line, out.lines = value.line, value.lines
            return out
        if isinstance(value, LineList):
            out = LineList(self(v, value.lines[i]) for i, v in enumerate(value))
            out.line, out.lines = value.line, value.lines
            return out
        return value

    def _string(self, text: str, line: int) -> Any:
        whole = _SUBST.fullmatch(text)
        if whole:
            value = self._value(whole, line)
            return env_scalar(value) if whole.group(1) == "env" else value
        return _SUBST.sub(lambda m: str(self._value(m, line)), text)

    def _value(self, m: re.Match, line: int) -> Any:
        kind, name, default = m.group(1), m.group(2), m.group(3)
        if kind == "dirname":
            return str(self.dirname)
        if kind == "env":
            if name in os.environ:
                return os.environ[name]
            if default is None:
                self.err(f"environment variable {name!r} is not set", line, key=f"$(env {name})")
                return ""
            return default
        if name not in self.args:
            self.err(f"undeclared argument {name!r} in substitution (declare it under 'args:')", line,
                     key=f"$(arg {name})")
            return m.group(0)
        value = self.args[name]
        return m.group(0) if value is _NOT_GIVEN else value
