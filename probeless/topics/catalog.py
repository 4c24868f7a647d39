"""The topics of a running graph, from its plan: node outputs and each node's diagnostics."""

from __future__ import annotations

import difflib
import sys
from dataclasses import dataclass, field
from typing import IO

from probeless.errors import ProbelessError
from probeless.topics.discovery import RunningGraph


@dataclass
class Subscriber:
    node: str
    input: str
    policy: str
    queue_size: int


@dataclass
class Topic:
    name: str                   # "<node_id>/<output>"
    type_name: str | None       # registered message type, None when unknown
    publisher: str              # node id
    node_type: str              # the publisher's ``node:`` entry
    endpoint: str               # the publisher's endpoint
    subscribers: list[Subscriber] = field(default_factory=list)
    declared: bool = True       # False for a topic guessed from "<node>/<output>" (dynamic family output)
    expected: int = 0           # subscribers the publisher's readiness barrier waits for


def _class_output_type(node_type: str, output: str) -> str | None:
    from probeless.runtime.node import output_type
    from probeless.runtime.registry import resolve_node

    try:
        _, typ = output_type(resolve_node(node_type), output)
    except Exception:  # unimportable node module here: the type is simply unknown
        return None
    return getattr(typ, "TYPE_NAME", None) or None


def graph_topics(graph: RunningGraph) -> dict[str, Topic]:
    """Every topic of the graph: node outputs and each node's ``<id>/diagnostics``, in node order."""
    from probeless.messages.diagnostics import NodeStatus

    nodes = graph.plan["nodes"]
    wired: dict[str, list[dict]] = {}
    for nid, node in nodes.items():
        for inp in node.get("inputs", []):
            if "topic" in inp:
                wired.setdefault(inp["topic"], []).append(dict(inp, node_id=nid))
        clock = node.get("clock")
        if clock:  # replay: every node follows the player's clock (a block input of 64, see process.py)
            wired.setdefault(clock["topic"], []).append({"node_id": nid, "name": "(clock)", "policy": "block",
                                                         "queue_size": 64, "type_name": "core/Clock"})
    topics: dict[str, Topic] = {}
    for nid, node in nodes.items():
        outputs = dict(node.get("outputs", {}))
        outputs.setdefault("diagnostics", {"topic": f"{nid}/diagnostics"})
        for out, spec in outputs.items():
            name = spec.get("topic", f"{nid}/{out}")
            subs = wired.get(name, [])
            if out == "diagnostics":
                type_name = NodeStatus.TYPE_NAME
            else:
                type_name = next((s["type_name"] for s in subs if s.get("type_name")), None)
                type_name = type_name or spec.get("type_name") or _class_output_type(node["node"], out)
            topics[name] = Topic(name, type_name, nid, node["node"], node["endpoint"],
                                 [Subscriber(s["node_id"], s["name"], s["policy"], s["queue_size"]) for s in subs],
                                 expected=max(len(subs), int(spec.get("subscribers") or 0)))
    return topics


def find_topic(graph: RunningGraph, name: str) -> Topic:
    """The topic called ``name``; an undeclared output of a known node is allowed (family outputs)."""
    topics = graph_topics(graph)
    if name in topics:
        return topics[name]
    node_id, sep, output = name.rpartition("/")
    nodes = graph.plan["nodes"]
    while sep and node_id not in nodes and "/" in node_id:   # output names may contain '/'
        node_id, _, head = node_id.rpartition("/")
        output = f"{head}/{output}"
    if sep and node_id in nodes and output:
        from probeless.runtime.node import output_type
        from probeless.runtime.registry import resolve_node

        node = nodes[node_id]
        try:
            declared, typ = output_type(resolve_node(node["node"]), output)
        except Exception:
            declared, typ = True, None  # cannot check here: let the user try
        if declared:
            return Topic(name, getattr(typ, "TYPE_NAME", None), node_id, node["node"], node["endpoint"],
                         declared=False)
    close = difflib.get_close_matches(name, list(topics), n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else f"; topics: {', '.join(topics)}"
    raise ProbelessError(f"no topic {name!r} in {graph.plan.get('file', 'the graph')}{hint}")


def _import_publisher(topic: Topic) -> None:
    """Import the publisher's node module so message types it registers can be decoded."""
    from probeless.runtime.registry import resolve_node

    try:
        resolve_node(topic.node_type)
    except Exception:
        pass


def list_topics(graph: RunningGraph, *, verbose: bool = False, out: IO[str] | None = None) -> list[Topic]:
    """Print one line per topic: topic, type, publisher, subscriber count (``verbose``: who and how)."""
    out = out or sys.stdout
    topics = list(graph_topics(graph).values())
    rows = [(t.name, t.type_name or "?", t.publisher, str(max(len(t.subscribers), t.expected))) for t in topics]
    heads = ("TOPIC", "TYPE", "PUBLISHER", "SUBSCRIBERS")
    widths = [max(len(r[i]) for r in rows + [heads]) for i in range(4)]
    print("  ".join(h.ljust(w) for h, w in zip(heads, widths)).rstrip(), file=out)
    for t, r in zip(topics, rows):
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip(), file=out)
        if verbose:
            print(f"    publisher {t.publisher} ({t.node_type}) at {t.endpoint}", file=out)
            for s in t.subscribers:
                print(f"    -> {s.node}.{s.input}  policy {s.policy}  queue_size {s.queue_size}", file=out)
    return topics
