"""Graph transforms for recording and replaying: add a bag recorder, swap source nodes for a player.

``add_player`` replaces the nodes whose outputs a recording holds (all of them by default, or the
ones named) with one ``bag_player`` that publishes the recorded topics under the same names, so
the rest of the graph runs unchanged on recorded data. This is how a node is swapped for an
experiment: replay the inputs, run the new node, compare.
"""

from __future__ import annotations

from probeless.errors import BagError, GraphError
from probeless.launch.graph import Graph, InputDecl, NodeDecl
from probeless.launch.validate import split_source
from probeless.runtime.node import input_type
from probeless.runtime.queues import input_queue_bytes
from probeless.runtime.registry import resolve_node

PLAYER_ID = "bag_player"
RECORDER_ID = "bag_recorder"


def parse_remaps(remaps: tuple[str, ...]) -> dict[str, str]:
    """``("a:=b", ...)`` -> ``{"a": "b"}``; ValueError on a malformed item."""
    out = {}
    for item in remaps:
        src, sep, dst = item.partition(":=")
        if not sep or not src or not dst:
            raise ValueError(f"remap {item!r} is not of the form from:=to")
        out[src] = dst
    return out


def node_topics(graph: Graph, decl: NodeDecl, diagnostics: bool = False) -> dict[str, str]:
    """output -> topic of a validated node (the outputs its launch plan will carry)."""
    cls = graph.node_classes[decl.id]
    names = decl.outputs if decl.outputs is not None else [o for o in cls.OUTPUTS if not o.endswith("*")]
    out = {o: decl.topics.get(o, f"{decl.id}/{o}") for o in names}
    wired = {split_source(graph, i.source) for d in graph.nodes.values() for i in d.inputs.values()
             if i.timer_period_ns is None}
    for _, o in (w for w in wired if w and w[0] == decl.id):
        out.setdefault(o, decl.topics.get(o, f"{decl.id}/{o}"))
    if diagnostics:
        out["diagnostics"] = f"{decl.id}/diagnostics"
    return out


def add_recorder(graph: Graph, path: str, *, topics: list[str] | None = None, diagnostics: bool = True,
                 params: dict | None = None, skip: set[str] = frozenset()) -> list[str]:
    """Wire a ``bag_recorder`` to ``topics`` (default: every topic); returns the recorded topics."""
    available: dict[str, tuple[str, str]] = {}
    for decl in graph.nodes.values():
        if decl.id in skip:
            continue
        for out, topic in node_topics(graph, decl, diagnostics).items():
            available[topic] = (decl.id, out)
    chosen = topics or sorted(available)
    if not chosen:
        raise GraphError("nothing to record: no node left in the graph publishes a topic", file=graph.file)
    unknown = [t for t in chosen if t not in available]
    if unknown:
        raise GraphError(f"cannot record {unknown}: not a topic of this graph (topics: {sorted(available)})",
                         file=graph.file)
    share = input_queue_bytes(len(chosen))  # the recorder's queues together stay under RECORDER_QUEUE_BYTES
    inputs = {t: InputDecl(t, f"{available[t][0]}/{available[t][1]}", "block", 256, max_bytes=share) for t in chosen}
    graph.nodes[RECORDER_ID] = NodeDecl(RECORDER_ID, "bag_recorder", graph.file, 0, inputs=inputs,
                                        params={"path": path, **(params or {})})
    graph.node_classes[RECORDER_ID] = resolve_node("bag_recorder")
    return chosen


def add_player(graph: Graph, bag: str, recorded: dict[str, str], *, replace: list[str] | None = None,
               remap: dict[str, str] | None = None, params: dict | None = None) -> list[str]:
    """Swap source nodes for a ``bag_player``; ``recorded`` maps recorded topic -> type name.

    Returns the ids of the replaced nodes. Raises GraphError/BagError naming the topic at fault.
    """
    remap = remap or {}
    played = {remap.get(t, t): (t, typ) for t, typ in recorded.items()}
    outputs = {d.id: node_topics(graph, d) for d in graph.nodes.values()}
    if replace is None:
        replace = [n for n, outs in outputs.items() if outs and all(t in played for t in outs.values())]
        if not replace:
            raise BagError(f"{bag}: no node's outputs are all in the recording; name the nodes with --replace "
                           f"(recorded topics: {sorted(played)})")
    for node_id in replace:
        if node_id not in graph.nodes:
            raise GraphError(f"--replace: no node {node_id!r} in the graph", file=graph.file)
        absent = [t for t in outputs[node_id].values() if t not in played]
        if absent:
            raise BagError(f"{bag}: cannot replace node {node_id!r}: topic(s) {absent} not in the recording")
    needed: dict[str, str] = {}
    for decl in graph.nodes.values():
        if decl.id in replace:
            continue
        for inp in decl.inputs.values():
            src = split_source(graph, inp.source) if inp.timer_period_ns is None else None
            if not src or src[0] not in replace:
                continue
            topic = outputs[src[0]].get(src[1], f"{src[0]}/{src[1]}")
            _check_type(graph, decl, inp, topic, played[topic][1], bag)
            needed[topic] = played[topic][0]
            inp.source = f"{PLAYER_ID}/{topic}"
    for node_id in replace:
        for topic in outputs[node_id].values():
            needed.setdefault(topic, played[topic][0])
        del graph.nodes[node_id]
        graph.node_classes.pop(node_id, None)
    player_params = {"path": bag, "topics": sorted(set(needed.values())),
                     "remap": [f"{a}:={b}" for a, b in sorted(remap.items())], **(params or {})}
    add_player_node(graph, player_params, {t: played[t][1] for t in needed})
    return list(replace)


def add_player_node(graph: Graph, params: dict, topic_types: dict[str, str]) -> None:
    """Add the ``bag_player`` node publishing ``topic_types`` (played topic -> type name) under those names."""
    graph.nodes[PLAYER_ID] = NodeDecl(PLAYER_ID, "bag_player", graph.file, 0, outputs=sorted(topic_types),
                                      params=params, topics={t: t for t in topic_types},
                                      output_types=dict(topic_types))
    graph.node_classes[PLAYER_ID] = resolve_node("bag_player")


def _check_type(graph: Graph, decl: NodeDecl, inp: InputDecl, topic: str, type_name: str, bag: str) -> None:
    _, want = input_type(graph.node_classes[decl.id], inp.name)
    if want is not None and want.TYPE_NAME != type_name:
        raise BagError(f"{bag}: topic {topic!r} is {type_name}, but input {inp.name!r} of node {decl.id!r} "
                       f"expects {want.TYPE_NAME}")
