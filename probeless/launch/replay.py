"""Graph transforms for recording and replaying: add a bag recorder, swap source nodes for a player.

``add_player`` replaces the nodes whose outputs a recording holds (all of them by default, or the
ones named) with one ``bag_player`` that publishes the recorded topics under the same names, so
the rest of the graph runs unchanged on recorded data. This is how a node is swapped for an
experiment: replay the inputs, run the new node, compare.
"""

from __future__ import annotations

import json
from pathlib import Path

from probeless.errors import BagError, GraphError
from probeless.launch.graph import Graph, InputDecl, NodeDecl
from probeless.launch.validate import split_source
from probeless.runtime.latching import default_latched, is_latched
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
               remap: dict[str, str] | None = None, params: dict | None = None,
               recorded_nodes: dict[str, str] | None = None, keep: list[str] | None = None,
               notes: list[str] | None = None, recorded_params: dict[str, dict] | None = None) -> list[str]:
    """Swap source nodes for a ``bag_player``; ``recorded`` maps recorded topic -> type name.

    ``recorded_nodes`` (node id -> ``node:`` type of the recorded graph) and ``recorded_params`` (node id ->
    params) mark swaps: a node whose type or params differ from the recorded ones runs live, and so does
    every node it feeds, unless ``replace`` names it. ``keep`` names nodes that run live anyway. ``notes``
    receives one line per decision (what comes from the recording, what runs live and why). Returns the ids
    of the replaced nodes.
    Raises GraphError/BagError naming the node or topic at fault.
    """
    remap = remap or {}
    played = {remap.get(t, t): (t, typ) for t, typ in recorded.items()}
    outputs = {d.id: node_topics(graph, d) for d in graph.nodes.values()}
    keep = list(keep or [])
    for node_id in keep + list(replace or []):
        if node_id not in graph.nodes:
            flag = "--keep" if node_id in keep else "--replace"
            raise GraphError(f"{flag}: no node {node_id!r} in the graph (nodes: {', '.join(graph.nodes)})",
                             file=graph.file)
    both = sorted(set(keep) & set(replace or []))
    if both:
        raise GraphError(f"node(s) {both} are in both --replace and --keep", file=graph.file)
    recordable = [n for n, outs in outputs.items() if outs and all(t in played for t in outs.values())]
    changed = {n: what for n, what in swapped_nodes(graph, recorded_nodes or {}, recorded_params or {}).items()
               if n in recordable}  # a node the recording could stand in for, and whose type or params changed
    # a source (no input but timers) with other params (a count, a duration) is still what a replay replaces
    sources = {n for n, what in changed.items() if "recorded with " in what and not _has_wired_inputs(graph, n)}
    swapped = {n: what for n, what in changed.items() if n not in sources}
    lines = [f"{n}: {what}: " + ("replaced by the recording (--replace names it)" if replace is not None
                                  and n in replace else f"running {graph.nodes[n].node} live")
             for n, what in swapped.items()]
    lines += [f"{n}: {changed[n]}: a source, replaced by the recording (--keep {n} runs it live)" for n in sources]
    fed: dict[str, str] = {}
    if replace is None:
        roots = [n for n in graph.nodes if n in swapped or n in keep]
        fed = downstream(graph, roots)
        replace = [n for n in recordable if n not in swapped and n not in keep and n not in fed]
        if not replace:
            live = "; ".join(lines) + "; " if lines else ""
            raise BagError(f"{bag}: no node left for the recording to replace: {live}name the nodes with "
                           f"--replace (recorded topics: {sorted(played)})")
    for node_id in replace:
        absent = [t for t in outputs[node_id].values() if t not in played]
        if absent:
            raise BagError(f"{bag}: cannot replace node {node_id!r}: topic(s) {absent} not in the recording")
    if notes is not None:
        notes += lines + _plan_lines(graph, replace, keep, swapped, fed)
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
    latched: dict[str, bool] = {}  # a replaced node's ``latched:`` choices, carried to the player's topics
    for node_id in replace:
        for out, topic in outputs[node_id].items():
            needed.setdefault(topic, played[topic][0])
            if is_latched(out, graph.nodes[node_id].latched) != default_latched(topic):
                latched[topic] = is_latched(out, graph.nodes[node_id].latched)
        del graph.nodes[node_id]
        graph.node_classes.pop(node_id, None)
    player_params = {"path": bag, "topics": sorted(set(needed.values())),
                     "remap": [f"{a}:={b}" for a, b in sorted(remap.items())], **(params or {})}
    add_player_node(graph, player_params, {t: played[t][1] for t in needed}, latched)
    return list(replace)


def swapped_nodes(graph: Graph, recorded_nodes: dict[str, str],
                  recorded_params: dict[str, dict] | None = None) -> dict[str, str]:
    """node id -> what differs (``recorded as X, graph has Y`` or the params), for the graph's nodes whose
    type or params differ from the recording's."""
    out = {}
    for node_id, decl in graph.nodes.items():
        rec = recorded_nodes.get(node_id)
        if rec is None or node_id in (PLAYER_ID, RECORDER_ID):
            continue
        if rec != decl.node and not _same_class(graph, decl, rec):
            out[node_id] = f"recorded as {rec}, graph has {decl.node}"
            continue
        params = (recorded_params or {}).get(node_id)
        if params is not None:
            changed = sorted(k for k in set(params) | set(decl.params)
                             if json.dumps(params.get(k), default=str) != json.dumps(decl.params.get(k), default=str))
            if changed:
                was = ", ".join(f"{k}={params.get(k)!r}" for k in changed)
                now = ", ".join(f"{k}={decl.params.get(k)!r}" for k in changed)
                out[node_id] = f"recorded with {was}, graph has {now}"
    return out


def _has_wired_inputs(graph: Graph, node_id: str) -> bool:
    return any(i.timer_period_ns is None for i in graph.nodes[node_id].inputs.values())


def _same_class(graph: Graph, decl: NodeDecl, recorded: str) -> bool:
    """The same class under another spelling (registered name vs module:Class) is no swap."""
    try:
        return resolve_node(recorded, base=Path(decl.file).parent) is graph.node_classes.get(decl.id)
    except GraphError:
        return False


def downstream(graph: Graph, roots: list[str]) -> dict[str, str]:
    """Every node fed, directly or through others, by one of ``roots``: node id -> the root feeding it."""
    consumers: dict[str, list[str]] = {}
    for decl in graph.nodes.values():
        for inp in decl.inputs.values():
            src = split_source(graph, inp.source) if inp.timer_period_ns is None else None
            if src:
                consumers.setdefault(src[0], []).append(decl.id)
    out: dict[str, str] = {}
    for root in roots:
        todo = list(consumers.get(root, []))
        while todo:
            node_id = todo.pop()
            if node_id not in out and node_id not in roots:
                out[node_id] = root
                todo += consumers.get(node_id, [])
    return out


def _plan_lines(graph: Graph, replace: list[str], keep: list[str], swapped: dict[str, str],
                fed: dict[str, str]) -> list[str]:
    """``from the recording: ...`` and ``live: ...`` (each with the reason when it is not the usual one)."""
    def why(node_id: str) -> str:
        if node_id in swapped:
            return " (swapped)"
        if node_id in keep:
            return " (--keep)"
        if node_id in fed:
            return f" (fed by {fed[node_id]})"
        return ""
    live = [f"{n}{why(n)}" for n in graph.nodes if n not in replace and n not in (PLAYER_ID, RECORDER_ID)]
    return [f"from the recording: {', '.join(f'{n} ({graph.nodes[n].node})' for n in replace)}",
            f"live: {', '.join(live) or 'none'}"]


def add_player_node(graph: Graph, params: dict, topic_types: dict[str, str],
                    latched: dict[str, bool] | None = None) -> None:
    """Add the ``bag_player`` node publishing ``topic_types`` (played topic -> type name) under those names;
    ``latched`` (topic -> bool) overrides which are latched (by default by name: runtime/latching.py)."""
    graph.nodes[PLAYER_ID] = NodeDecl(PLAYER_ID, "bag_player", graph.file, 0, outputs=sorted(topic_types),
                                      params=params, topics={t: t for t in topic_types},
                                      output_types=dict(topic_types), latched=dict(latched or {}))
    graph.node_classes[PLAYER_ID] = resolve_node("bag_player")


def _check_type(graph: Graph, decl: NodeDecl, inp: InputDecl, topic: str, type_name: str, bag: str) -> None:
    _, want = input_type(graph.node_classes[decl.id], inp.name)
    if want is not None and want.TYPE_NAME != type_name:
        raise BagError(f"{bag}: topic {topic!r} is {type_name}, but input {inp.name!r} of node {decl.id!r} "
                       f"expects {want.TYPE_NAME}")
