"""``probeless graph``: draw a validated launch graph as Mermaid, Graphviz DOT, PNG or SVG.

Nodes show their id and node type; each wired input is an edge ``output → input`` labelled with
the message type and, when not the default (drop_oldest/10), the queue policy. Built-in timer
inputs are drawn as small timer nodes (``timer 30 Hz``). PNG and SVG need the Graphviz ``dot``
program (Debian package ``graphviz``).
"""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from probeless.errors import ProbelessError
from probeless.launch.graph import DEFAULT_QUEUE, Graph, InputDecl
from probeless.launch.validate import split_source
from probeless.runtime.node import output_type

FORMATS = ("mermaid", "dot", "png", "svg")
SUFFIXES = {".png": "png", ".svg": "svg", ".dot": "dot", ".gv": "dot", ".mmd": "mermaid", ".md": "mermaid"}
_TIMER_UNITS = {"hz": "Hz", "ms": "ms", "s": "s"}


@dataclass
class Edge:
    """One drawn edge: ``src`` and ``dst`` are node ids or timer keys; ``lines`` form the label."""

    src: str
    dst: str
    lines: list[str]


def draw(graph: Graph, fmt: str | None, out: str | None) -> str:
    """Render ``graph`` (validated: ``graph.node_classes`` filled) and write ``out`` when given.

    ``fmt`` is one of :data:`FORMATS`; None infers it from the suffix of ``out`` (.png, .svg,
    .dot/.gv, .mmd/.md) or means mermaid when ``out`` is None. Returns the text: Mermaid or DOT
    source (for png/svg the DOT source that was rendered). Raises ProbelessError when the format
    is unknown, png/svg has no ``out``, or Graphviz is missing or fails.
    """
    if fmt is None:
        fmt = "mermaid" if out is None else SUFFIXES.get(Path(out).suffix.lower())
        if fmt is None:
            raise ProbelessError(f"cannot tell the format from {out!r} (use .png, .svg, .dot, .gv, .mmd or .md, "
                                 f"or give --format)")
    if fmt not in FORMATS:
        raise ProbelessError(f"unknown graph format {fmt!r} (use {', '.join(FORMATS)})")
    timers, edges = _collect(graph)
    if fmt == "mermaid":
        text = to_mermaid(graph, timers, edges)
        if out is not None and Path(out).suffix.lower() == ".md":
            text = f"```mermaid\n{text}```\n"
    else:
        text = to_dot(graph, timers, edges)
    if out is None:
        if fmt in ("png", "svg"):
            raise ProbelessError(f"format {fmt} needs an output file (--out FILE.{fmt})")
        return text
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    if fmt in ("png", "svg"):
        _render(text, fmt, out)
    else:
        Path(out).write_text(text, encoding="utf-8")
    return text


def _collect(graph: Graph) -> tuple[dict[str, str], list[Edge]]:
    """Timer nodes (key -> label) and edges of a validated graph, in declaration order."""
    timers: dict[str, str] = {}
    edges: list[Edge] = []
    for decl in graph.nodes.values():
        for inp in decl.inputs.values():
            policy = _policy(inp)
            if inp.timer_period_ns is not None:
                key = f"timer:{decl.id}/{inp.name}"
                _, unit, value = inp.source.split("/")
                timers[key] = f"timer {value} {_TIMER_UNITS[unit]}"
                edges.append(Edge(key, decl.id, [inp.name] + policy))
                continue
            if inp.external is not None:  # a topic of another running graph: drawn as a source of its own
                key = f"external:{inp.external}"
                timers[key] = f"{inp.external}: {inp.source.partition(':')[2]}"
                edges.append(Edge(key, decl.id, [inp.name] + policy))
                continue
            src_id, output = split_source(graph, inp.source)
            _, typ = output_type(graph.node_classes[src_id], output)
            type_name = typ.TYPE_NAME if typ is not None else "any type"
            edges.append(Edge(src_id, decl.id, [f"{output} → {inp.name}", type_name] + policy))
    return timers, edges


def _policy(inp: InputDecl) -> list[str]:
    if inp.policy == DEFAULT_QUEUE["policy"] and inp.queue_size == DEFAULT_QUEUE["queue_size"]:
        return []
    return [inp.policy if inp.policy == "latest" else f"{inp.policy}/{inp.queue_size}"]


def _dq(text: str) -> str:
    """A DOT double-quoted string (escString: backslashes and quotes escaped)."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _dot_label(lines: list[str]) -> str:
    return _dq("\n".join(lines)).replace("\n", "\\n")


def to_dot(graph: Graph, timers: dict[str, str], edges: list[Edge]) -> str:
    """Graphviz DOT source of the collected graph."""
    out = ["digraph probeless {", "  rankdir=LR;", '  graph [fontname="Helvetica"];',
           '  node [shape=box, style="rounded,filled", fillcolor="#e8f0fe", color="#4a6fa5", fontname="Helvetica"];',
           '  edge [fontname="Helvetica", fontsize=10, color="#555555"];']
    for decl in graph.nodes.values():
        out.append(f"  {_dq(decl.id)} [label={_dot_label([decl.id, decl.node])}];")
    for key, label in timers.items():
        out.append(f'  {_dq(key)} [label={_dq(label)}, shape=ellipse, style="dashed,filled", '
                   f'fillcolor="#fff7e0", fontsize=10];')
    for e in edges:
        out.append(f"  {_dq(e.src)} -> {_dq(e.dst)} [label={_dot_label(e.lines)}];")
    out.append("}")
    return "\n".join(out) + "\n"


def _mq(lines: list[str]) -> str:
    """A Mermaid quoted label; entity codes for characters Mermaid would parse."""
    table = str.maketrans({"#": "#35;", '"': "#quot;", "<": "#lt;", ">": "#gt;", "|": "#124;"})
    return '"' + "<br/>".join(line.translate(table) for line in lines) + '"'


def to_mermaid(graph: Graph, timers: dict[str, str], edges: list[Edge]) -> str:
    """Mermaid ``flowchart LR`` text of the collected graph (ids are n0.., t0.., labels quoted)."""
    ids = {node_id: f"n{i}" for i, node_id in enumerate(graph.nodes)}
    ids.update({key: f"t{i}" for i, key in enumerate(timers)})
    out = ["flowchart LR"]
    for decl in graph.nodes.values():
        out.append(f"  {ids[decl.id]}[{_mq([decl.id, decl.node])}]")
    for key, label in timers.items():
        out.append(f"  {ids[key]}([{_mq([label])}])")
    for e in edges:
        out.append(f"  {ids[e.src]} -->|{_mq(e.lines)}| {ids[e.dst]}")
    if timers:
        out.append("  classDef timer fill:#fff7e0,stroke:#b08800,stroke-dasharray:4 2")
        out.append(f"  class {','.join(ids[k] for k in timers)} timer")
    return "\n".join(out) + "\n"


def _render(dot_text: str, fmt: str, out: str) -> None:
    exe = shutil.which("dot")
    if exe is None:
        raise ProbelessError(f"drawing {fmt} needs the Graphviz 'dot' program: install graphviz "
                             f"(e.g. apt install graphviz), or use --format dot / mermaid")
    dpi = ["-Gdpi=144"] if fmt == "png" else []  # 72 dpi default is too small to read edge labels
    proc = subprocess.run([exe, f"-T{fmt}", *dpi, "-o", out], input=dot_text.encode("utf-8"),
                          capture_output=True, timeout=60)
    if proc.returncode != 0:
        raise ProbelessError(f"dot -T{fmt} failed: {proc.stderr.decode(errors='replace').strip()}")
