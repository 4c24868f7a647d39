"""Launch-file arguments and substitutions: ``$(arg NAME)``, ``$(env NAME [default])``, ``$(dirname)``,
``$(cwd)`` (the working folder: for an input that an earlier run wrote under ``out/``),
``$(given NAME THEN ELSE)`` (``THEN`` when argument ``NAME`` was passed, on the command line or by the
including file, else ``ELSE``: e.g. ``lighting: {default: $(given photo hdr ldr)}``)."""

from __future__ import annotations

import difflib
import os
import re
from pathlib import Path
from typing import Any

from probeless.errors import GraphError
from probeless.launch.relpath import Rooted
from probeless.launch.yamlload import LineDict, LineList

_SUBST = re.compile(r"\$\((arg|env|dirname|cwd|given)(?:\s+([^)\s]+))?(?:\s+([^)]*))?\)")
_NOT_GIVEN = object()  # a required argument that was not passed (reported once, not at every use)


def resolve_args(decl: Any, overrides: dict, err, line: int, is_root: bool, cli_err=None) -> dict:
    """Argument values: CLI/include overrides, else defaults; reports missing and unknown arguments and values
    outside a declared ``min``/``max``/``choices``. ``cli_err(GraphError)`` receives the problems of the
    command line itself (an unknown ``name:=``, a value out of range), reported as such, not at a file line."""
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
        problem = _range_problem(spec, out[name]) if out[name] is not _NOT_GIVEN else None
        if problem and name in overrides and is_root and cli_err is not None:
            cli_err(GraphError(f"argument {name}:={overrides[name]}: {problem}", file="command line"))
            out[name] = _NOT_GIVEN  # reported once here, not again where it is used
        elif problem:
            err(f"{'value' if name in overrides else 'default'} {out[name]!r}: {problem}", decl.line_of(name),
                key=f"args.{name}")
            out[name] = _NOT_GIVEN
    for name in overrides:
        if name not in decl and is_root:
            close = difflib.get_close_matches(str(name), [str(k) for k in decl], n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            msg = f"unknown argument {name!r} ({hint}declared: {', '.join(map(str, decl)) or 'none'})"
            if cli_err is not None:
                cli_err(GraphError(f"argument {name}:={overrides[name]}: {msg}", file="command line"))
            else:
                err(msg, line, key=name)
    return out


def _range_problem(spec: Any, value: Any) -> str | None:
    """What is wrong with an argument's value by its declaration's ``min``, ``max`` and ``choices``, or None."""
    if not isinstance(spec, dict):
        return None
    lo, hi, choices = spec.get("min"), spec.get("max"), spec.get("choices")
    if choices is not None and value not in choices:
        return f"{value!r} is not one of {list(choices)}"
    if lo is None and hi is None:
        return None
    allowed = _allowed(lo, hi)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f"expected a number ({allowed}), got {value!r}"
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        return f"{value} is out of range ({allowed})"
    return None


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
    """Applies $(arg)/$(env)/$(dirname)/$(given) to every string in a value; ``given``: the names of the
    arguments that were passed (not defaulted)."""

    def __init__(self, args: dict, dirname: Path, err, given=frozenset()):
        self.args, self.dirname, self.err, self.given = args, dirname, err, frozenset(given)

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
        bases = []  # a command-line value pasted into a longer string keeps its origin (launch/relpath.py)

        def one(m: re.Match) -> str:
            value = self._value(m, line)
            if isinstance(value, Rooted):
                bases.append(value.base)
            return str(value)
        out = _SUBST.sub(one, text)
        return Rooted(out, bases[0]) if bases else out

    def _value(self, m: re.Match, line: int) -> Any:
        kind, name, default = m.group(1), m.group(2), m.group(3)
        if kind == "dirname":
            return os.path.abspath(self.dirname)  # absolute: an include taking it keeps the same file
        if kind == "cwd":
            return os.getcwd()
        if kind == "given":
            return self._given(name, default, line)
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

    def _given(self, name: str | None, choices: str | None, line: int) -> str:
        words = (choices or "").split()
        if name is None or len(words) != 2:
            self.err("$(given NAME THEN ELSE) takes an argument name and two words", line, key="$(given)")
            return ""
        if name not in self.args:
            self.err(f"undeclared argument {name!r} in substitution (declare it under 'args:')", line,
                     key=f"$(given {name})")
            return ""
        return words[0] if name in self.given else words[1]


def _allowed(lo: Any, hi: Any) -> str:
    if lo is not None and hi is not None:
        return f"allowed: {lo} to {hi}"
    return f"allowed: >= {lo}" if lo is not None else f"allowed: <= {hi}"


def describe_args(path: str | Path) -> str:
    """``probeless launch GRAPH --show-args``: the top-level arguments with default, allowed values and doc."""
    from probeless.launch.yamlload import load_yaml

    doc = load_yaml(Path(path))
    decl = doc.get("args") if isinstance(doc, dict) else None
    if not isinstance(decl, dict) or not decl:
        return f"{path} takes no arguments"
    lines = [f"Arguments of {path} (pass as name:=value):", ""]
    for name, spec in decl.items():
        spec = spec if isinstance(spec, dict) else {"default": spec}
        facts = [f"default: {spec['default']!r}" if "default" in spec else "required"]
        if spec.get("choices") is not None:
            facts.append(f"one of {list(spec['choices'])}")
        if spec.get("min") is not None or spec.get("max") is not None:
            facts.append(_allowed(spec.get("min"), spec.get("max")))
        lines.append(f"    {name}:")
        if spec.get("doc"):
            lines.append(f"        {spec['doc']}")
        lines.append(f"        ({', '.join(facts)})")
    return "\n".join(lines)
