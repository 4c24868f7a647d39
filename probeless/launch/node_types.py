"""``probeless nodes list|info``: the registered node types and their interface (like ``ros2 interface show``).

``list`` names every node type a graph's ``node:`` can use (built-ins and the ``probeless.nodes``
entry points of installed packages); ``info TYPE`` shows one type's inputs, outputs and params
(type, default, range, choices, doc). TYPE may also be ``module:Class`` or ``path/file.py:Class``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import typing
from typing import Any

from probeless.errors import GraphError
from probeless.runtime.params import describe_type
from probeless.runtime.registry import builtin_names, node_types, resolve_node


def _type_name(typ: Any) -> str:
    return getattr(typ, "TYPE_NAME", None) or "any"


def _summary(cls: type) -> str:
    doc = (cls.__doc__ or "").strip()
    return doc.splitlines()[0] if doc else ""


def describe_node(name: str, base: str | None = None) -> dict[str, Any]:
    """Inputs, outputs and params of a node type as a JSON-able dict; GraphError when it cannot be loaded."""
    cls = resolve_node(name, base=base)
    hints = typing.get_type_hints(cls.Params)
    params = []
    for f in dataclasses.fields(cls.Params):
        meta = f.metadata
        entry = {"name": f.name, "type": describe_type(hints[f.name]),
                 "default": None if f.default is dataclasses.MISSING else f.default,
                 "required": f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING,
                 "doc": meta.get("doc", "")}
        for key in ("min", "max", "choices", "length", "min_length", "max_length", "path"):
            if meta.get(key) is not None:
                entry[key] = list(meta[key]) if isinstance(meta[key], tuple) else meta[key]
        if meta.get("must_exist"):
            entry["must_exist"] = True
        if meta.get("dynamic"):
            entry["dynamic"] = True
        params.append(entry)
    target = node_types().get(name, name)
    return {"type": name, "class": f"{cls.__module__}:{cls.__qualname__}", "target": target,
            "builtin": name in builtin_names(), "summary": _summary(cls), "doc": (cls.__doc__ or "").strip(),
            "inputs": {k: _type_name(v) for k, v in cls.INPUTS.items()},
            "outputs": {k: _type_name(v) for k, v in cls.OUTPUTS.items()},
            "params": params}


def list_nodes() -> list[dict[str, Any]]:
    """One entry per registered type: name, target, origin and summary (or the error loading it)."""
    out = []
    builtins = builtin_names()
    for name, target in sorted(node_types().items()):
        entry = {"type": name, "target": target, "origin": "builtin" if name in builtins else "entry point"}
        try:
            entry["summary"] = _summary(resolve_node(name))
        except GraphError as exc:
            entry["error"] = exc.message
        out.append(entry)
    return out


def format_info(d: dict[str, Any]) -> str:
    lines = [f"{d['type']}  ({d['target']})"]
    if d["doc"]:
        lines += [f"  {line}".rstrip() for line in d["doc"].splitlines()]
    lines.append("inputs:")
    lines += [f"  {k}: {v}" for k, v in d["inputs"].items()] or ["  (none)"]
    lines.append("outputs:")
    lines += [f"  {k}: {v}" for k, v in d["outputs"].items()] or ["  (none)"]
    lines.append("params:")
    for p in d["params"]:
        default = "(required)" if p["required"] else f"= {p['default']!r}"
        extra = [f"{k} {p[k]}" for k in ("min", "max", "choices", "length", "min_length", "max_length", "path")
                 if k in p]
        extra += [k for k in ("must_exist", "dynamic") if p.get(k)]
        lines.append(f"  {p['name']}: {p['type']} {default}" + (f"  [{', '.join(extra)}]" if extra else ""))
        if p["doc"]:
            lines.append(f"      {p['doc']}")
    if not d["params"]:
        lines.append("  (none)")
    return "\n".join(lines)


def cmd_nodes(ns: argparse.Namespace) -> int:
    if ns.nodes_command == "info":
        d = describe_node(ns.type, base=".")
        print(json.dumps(d, indent=2, default=str) if ns.json else format_info(d))
        return 0
    entries = list_nodes()
    if ns.json:
        print(json.dumps(entries, indent=2))
        return 0
    width = max(len(e["type"]) for e in entries)
    for e in entries:
        tail = e.get("summary", "") if "error" not in e else f"(cannot load: {e['error']})"
        origin = "" if e["origin"] == "builtin" else f"[{e['origin']}: {e['target']}] "
        print(f"{e['type']:<{width}}  {origin}{tail}")
    failed = [e for e in entries if "error" in e]
    if failed:
        print(f"warning: {len(failed)} node type(s) cannot be loaded here", file=sys.stderr)
    return 0


def add_nodes_parser(sub) -> None:
    p = sub.add_parser("nodes", help="the node types a graph can use: list them, show one's inputs/outputs/params")
    s = p.add_subparsers(dest="nodes_command", required=True)
    c = s.add_parser("list", help="every registered node type (built-in and installed entry points)")
    c.add_argument("--json", action="store_true", help="one JSON list")
    c.set_defaults(func=cmd_nodes)
    c = s.add_parser("info", help="inputs, outputs and params (types, defaults, ranges, docs) of a node type")
    c.add_argument("type", metavar="TYPE", help="a registered name, module:Class or path/to/file.py:Class")
    c.add_argument("--json", action="store_true", help="one JSON object")
    c.set_defaults(func=cmd_nodes)
