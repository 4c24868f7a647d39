"""``probeless bag info``: what a recording holds, as text or one JSON object.

Besides the MCAP contents it shows what the recorder stored as metadata records:
``probeless.incomplete`` (topic -> "N messages missing (seq gaps)") and ``probeless.graph``
(``plan`` as JSON text, ``version``, ``git_revision``, ``command``). Channels of other writers
(cdr, ros1, json, protobuf, ...) are listed too, with their message encoding and schema name
(``encoding``, ``schema_encoding`` and ``type`` in the JSON form).
"""

from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Sequence

from probeless.bag.format import MESSAGE_ENCODING
from probeless.bag.reader import BagReader
from probeless.bag.writer import INCOMPLETE, recording_paths

GRAPH = "probeless.graph"


def info_report(paths: str | Path | Sequence[str | Path]) -> dict[str, Any]:
    """Report on one recording (one file, several files, or the parts of a split recording)."""
    files, topics, metadata, warnings, compression = [], {}, {}, [], set()
    start = end = None
    for path in recording_paths(paths):
        with BagReader(path) as reader:
            files.append({"path": str(path), "size": path.stat().st_size, "truncated": reader.truncated,
                          "truncation_note": reader.truncation_note, "library": reader.library})
            if reader.truncated:
                warnings.append(f"{path}: {reader.truncation_note}")
            compression |= reader.compression
            for name, data in reader.metadata().items():
                metadata.setdefault(name, {}).update(data)
            found = reader.topics().values()
            warnings += reader.problems
            for t in found:
                d = topics.setdefault(t.topic, {"type": t.type_name, "version": t.version, "count": 0,
                                                "bytes": 0, "first_ns": None, "last_ns": None,
                                                "encoding": t.message_encoding,
                                                "schema_encoding": t.schema_encoding})
                d["count"] += t.count
                d["bytes"] += t.bytes
                if t.count:
                    d["first_ns"] = t.first_ns if d["first_ns"] is None else min(d["first_ns"], t.first_ns)
                    d["last_ns"] = t.last_ns if d["last_ns"] is None else max(d["last_ns"], t.last_ns)
            if reader.start_ns is not None:
                start = reader.start_ns if start is None else min(start, reader.start_ns)
                end = reader.end_ns if end is None else max(end, reader.end_ns)
    for d in topics.values():
        span = (d["last_ns"] - d["first_ns"]) if d["count"] > 1 else 0
        d["rate_hz"] = (d["count"] - 1) * 1e9 / span if span > 0 else None
    graph = _graph(metadata.pop(GRAPH, None), warnings)
    return {"files": files, "start_ns": start, "end_ns": end,
            "duration_s": (end - start) / 1e9 if start is not None else 0.0,
            "compression": sorted(compression), "message_count": sum(d["count"] for d in topics.values()),
            "topics": dict(sorted(topics.items())), "incomplete": metadata.pop(INCOMPLETE, {}),
            "graph": graph, "metadata": metadata, "warnings": warnings}


def _graph(meta: dict[str, str] | None, warnings: list[str]) -> dict[str, Any] | None:
    if meta is None:
        return None
    out: dict[str, Any] = {k: meta.get(k) for k in ("version", "git_revision", "command")}
    out.update(file=None, args={}, nodes={})
    try:
        plan = json.loads(meta.get("plan", "{}"))
        out["file"], out["args"] = plan.get("file") or meta.get("graph_file") or None, plan.get("args") or {}
        out["nodes"] = {nid: {"node": n.get("node"), "params": n.get("params") or {}}
                        for nid, n in (plan.get("nodes") or {}).items()}
    except (ValueError, AttributeError, TypeError) as exc:
        warnings.append(f"{GRAPH}: the stored plan is not valid JSON ({exc})")
    return out


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return ""


def _time(ns: int | None) -> str:
    if ns is None:
        return "-"
    stamp = datetime.fromtimestamp(ns / 1e9, tz=timezone.utc).isoformat(timespec="milliseconds")
    return f"{stamp} ({ns} ns)"


def _type(d: dict[str, Any]) -> str:
    """``type vN`` for a probeless topic, ``schema name [encoding]`` for another writer's channel."""
    if d.get("encoding", MESSAGE_ENCODING) == MESSAGE_ENCODING:
        return f"{d['type']} v{d['version']}"
    return f"{d['type'] or '(no schema)'} [{d['encoding'] or 'no encoding'}]"


def format_info(report: dict[str, Any]) -> str:
    """The text form of :func:`info_report`."""
    files = ", ".join(f"{f['path']} ({_size(f['size'])})" for f in report["files"])
    lines = [f"files:        {files}",
             f"duration:     {report['duration_s']:.3f} s",
             f"start:        {_time(report['start_ns'])}",
             f"end:          {_time(report['end_ns'])}",
             f"compression:  {', '.join(report['compression']) or '-'}",
             f"messages:     {report['message_count']}"]
    lines += [f"WARNING: {w}" for w in report["warnings"]]
    rows = [(t, _type(d), str(d["count"]),
             f"{d['rate_hz']:.2f} Hz" if d["rate_hz"] else "-", _size(d["bytes"]))
            for t, d in report["topics"].items()]
    if rows:
        head = ("topic", "type", "count", "rate", "size")
        widths = [max(len(r[i]) for r in rows + [head]) for i in range(5)]
        lines.append("topics:")
        for r in [head] + rows:
            lines.append("  " + "  ".join(c.rjust(w) if i >= 2 else c.ljust(w)
                                          for i, (c, w) in enumerate(zip(r, widths))).rstrip())
    if report["incomplete"]:
        lines.append("INCOMPLETE:")
        lines += [f"  {topic}: {what}" for topic, what in sorted(report["incomplete"].items())]
    g = report["graph"]
    if g is not None:
        lines += ["graph:", f"  probeless version: {g['version'] or '-'}",
                  f"  git revision:      {g['git_revision'] or '-'}",
                  f"  command:           {g['command'] or '-'}",
                  f"  graph file:        {g['file'] or '-'}"]
        if g["args"]:
            lines.append(f"  args:              {json.dumps(g['args'])}")
        lines.append("  nodes:")
        for nid, n in g["nodes"].items():
            lines.append(f"    {nid}: {n['node']} {json.dumps(n['params'], sort_keys=True)}")
    for name, data in sorted(report["metadata"].items()):
        shown = {k: v if len(v) <= 200 else f"{v[:80]!s}... ({len(v)} chars; --json shows all)"
                 for k, v in data.items()}
        lines.append(f"metadata {name}: {json.dumps(shown, sort_keys=True)}")
    return "\n".join(lines)

