"""``external:`` inputs: a node reads a topic of another graph that is already running.

::

    inputs:
      image: {source: src/image, external: upstream.yaml, policy: latest}   # or external: $(arg upstream)

``external`` names the other graph's run: its run id (``probeless runs``), its run directory, or
the graph file it was launched from (relative to this graph file). Exactly one running graph must
match: with several, ``check`` lists their run ids and asks for one, never guessing. The topic
must be one the other graph publishes, of the type the input expects. The input connects to the
publisher's lossy socket (``block`` is refused), so this graph can never hold up the other one,
and it ends when the other graph ends (end of stream).
"""

from __future__ import annotations

import difflib
from pathlib import Path

from probeless.errors import GraphError, ProbelessError
from probeless.launch.graph import EXTERNAL_PREFIX, InputDecl, NodeDecl
from probeless.runtime.runs import RunningGraph, resolve_runs


def external_topic(inp: InputDecl) -> str:
    """The other graph's topic an external input reads."""
    return inp.source[len(EXTERNAL_PREFIX):]


def _published(g: RunningGraph) -> dict[str, tuple[str, dict]]:
    """topic -> (publisher node id, its plan entry) of a running graph, diagnostics included."""
    out = {}
    for nid, node in g.plan["nodes"].items():
        out[f"{nid}/diagnostics"] = (nid, node)
        for spec in node.get("outputs", {}).values():
            out[spec.get("topic", "")] = (nid, node)
    return out


def _type_name(g: RunningGraph, topic: str, nid: str, node: dict) -> str | None:
    """The message type on ``topic`` of a running graph: from its wiring, else from the publisher's class."""
    if topic.endswith("/diagnostics"):
        return "diagnostics/NodeStatus"
    for other in g.plan["nodes"].values():
        for i in other.get("inputs", []):
            if i.get("topic") == topic and i.get("type_name"):
                return i["type_name"]
    from probeless.runtime.node import output_type
    from probeless.runtime.registry import resolve_node

    out = next((o for o, s in node.get("outputs", {}).items() if s.get("topic") == topic), None)
    if out is not None and node["outputs"][out].get("type_name"):
        return node["outputs"][out]["type_name"]
    try:
        _, typ = output_type(resolve_node(node["node"]), out or "")
    except Exception:  # cannot import the other graph's node here: the type stays unchecked
        return None
    return getattr(typ, "TYPE_NAME", None)


def check_external(decl: NodeDecl, inp: InputDecl, want: type | None) -> list[GraphError]:
    """Resolve an external input against the running graphs; fills ``inp.resolved`` when valid."""
    def error(msg: str) -> list[GraphError]:
        return [GraphError(msg, file=decl.file, line=inp.line, node_id=decl.id, key=f"inputs.{inp.name}")]

    try:
        runs = resolve_runs(inp.external, relative_to=Path(decl.file).parent)
    except ProbelessError as exc:
        return error(f"external: {exc}")
    if not runs:
        return error(f"external graph {inp.external!r} is not running; start it first "
                     f"(`probeless runs` lists the running graphs)")
    if len(runs) > 1:
        return error(f"{len(runs)} graphs launched from {inp.external!r} are running "
                     f"({', '.join(g.run_id for g in runs)}); name one by its run id, "
                     f"e.g. external: $(arg upstream) with upstream:=RUN_ID")
    g = runs[0]
    if g.plan.get("curve"):
        return error(f"external graph {g.run_id} uses CURVE security; external inputs read local graphs only")
    topic = external_topic(inp)
    published = _published(g)
    if topic not in published:
        close = difflib.get_close_matches(topic, list(published), n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        return error(f"external graph {g.run_id} ({g.plan.get('file', '?')}) publishes no topic {topic!r} "
                     f"({hint}topics: {', '.join(t for t in published if not t.endswith('/diagnostics'))})")
    nid, node = published[topic]
    type_name = _type_name(g, topic, nid, node)
    if want is not None and type_name is not None and want.TYPE_NAME != type_name:
        return error(f"type mismatch: {topic} of external graph {g.run_id} carries {type_name}, "
                     f"input {inp.name!r} expects {want.TYPE_NAME}")
    inp.resolved = {"run_id": g.run_id, "endpoint": node["endpoint"], "type_name": type_name,
                    "source_node": nid, "topic": topic}
    return []
