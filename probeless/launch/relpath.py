"""Where a relative path in a graph is taken from.

A relative input path (a param declared ``param(path=..., must_exist=True)``: scenes, recordings, photos,
calibrations, object files) is taken from the folder of the graph file that wrote it, whether it is
written in a node's ``params:``, as an argument's default, or in an include's ``args:``; a value given on
the command line (``scene:=my.yaml``) is taken from the working folder, as in a shell. Output paths
(``out_dir``, ``path`` of writers) are left as written: relative to the working folder.

While a graph is parsed, values that came from elsewhere than the file being parsed carry their origin
as a :class:`Rooted` string; ``probeless.launch.graph`` records it per param, and :func:`root_input_paths`
rewrites the params at validation, before they are checked and handed to the node.
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path
from typing import Any


class Rooted(str):
    """A string with the folder its relative paths are taken from (``base`` None: the working folder)."""

    base: str | None

    def __new__(cls, value: str, base: str | Path | None) -> Rooted:
        out = super().__new__(cls, value)
        out.base = None if base is None else str(base)
        return out


def rooted(value: Any, base: str | Path | None) -> Any:
    """``value`` tagged with ``base`` when it is a plain string (an already tagged one keeps its origin)."""
    if isinstance(value, str) and not isinstance(value, Rooted):
        return Rooted(value, base)
    return value


def untag(params: dict) -> tuple[dict, dict[str, str | None]]:
    """(params with plain strings, key -> base folder of each tagged top-level string)."""
    bases = {k: v.base for k, v in params.items() if isinstance(v, Rooted)}
    return {k: str(v) if isinstance(v, Rooted) else v for k, v in params.items()}, bases


def root_input_paths(params: dict, bases: dict[str, str | None], params_cls: type,
                     graph_dir: Path) -> dict[str, tuple[str, str]]:
    """Rewrite relative input-path params in place to be taken from their graph file's folder; returns
    key -> (the value as written, the folder it was taken from), for messages."""
    done = {}
    for f in dataclasses.fields(params_cls):
        value = params.get(f.name)
        if not f.metadata.get("must_exist") or not isinstance(value, str) or not value:
            continue
        if Path(value).expanduser().is_absolute():
            continue
        base = bases.get(f.name, str(graph_dir))
        if base is not None:
            params[f.name] = os.path.normpath(os.path.join(base, value))
            done[f.name] = (value, base)
    return done


def explain(errors: list, rooted: dict[str, tuple[str, str]]) -> list:
    """Errors about rooted params name the value as written and the graph folder it was taken from."""
    out = []
    for e in errors:
        written = rooted.get(e.key)
        if written is not None and e.message.startswith(os.path.normpath(os.path.join(written[1], written[0]))):
            resolved = os.path.normpath(os.path.join(written[1], written[0]))
            rest = re.sub(r" \(relative to the working folder [^)]*\)$", "", e.message[len(resolved):])
            message = f"{written[0]}{rest} (relative to the graph's folder {os.path.abspath(written[1])})"
            e = type(e)(message, file=e.file, line=e.line, node_id=e.node_id, key=e.key)
        out.append(e)
    return out
