"""Pattern inputs: one input wired to every topic of the graph that matches a glob.

::

    - id: viewer
      node: rerun_sink
      inputs:
        all: {source: "*", policy: latest, exclude: ["rig/gt/*"]}   # every topic but the ground truth

A source with ``*``, ``?`` or ``[`` is a pattern (``fnmatch``; ``*`` also matches ``/``). When the graph is
validated it becomes one input per matching topic, named by the topic, with the pattern input's policy,
queue size and byte bound; ``exclude`` lists patterns to leave out. Candidates are every output of every
other node, its ``diagnostics`` included, except the outputs of nodes that have pattern inputs themselves
(two viewers never subscribe to each other). A node's explicit inputs win over a pattern's. A pattern that
matches nothing is an error naming it, so a typo never leaves a viewer silently empty.
"""

from __future__ import annotations

import fnmatch
from dataclasses import replace

from probeless.errors import GraphError
from probeless.launch.graph import Graph, InputDecl, NodeDecl

GLOB_CHARS = frozenset("*?[")


def is_pattern(source: str) -> bool:
    """Whether an input source is a glob over topics rather than one ``node_id/output``."""
    return not source.startswith("timer/") and any(c in GLOB_CHARS for c in source)


def declared_topics(graph: Graph, decl: NodeDecl, classes: dict[str, type]) -> dict[str, str]:
    """topic -> output of the outputs a node declares (its ``outputs:`` list, else its class's fixed names),
    plus ``diagnostics``. Families (``envmap/*``) have no fixed names and are left out."""
    cls = classes[decl.id]
    names = decl.outputs if decl.outputs is not None else [o for o in cls.OUTPUTS if not o.endswith("*")]
    topics = {decl.topics.get(o, f"{decl.id}/{o}"): o for o in names}
    topics[f"{decl.id}/diagnostics"] = "diagnostics"
    return topics


def expand_patterns(graph: Graph, classes: dict[str, type]) -> list[GraphError]:
    """Replace every pattern input by one input per matching topic (in place); errors for empty matches.

    Nodes whose class could not be resolved (already reported) are skipped as sources and as subscribers."""
    globbing = {d.id for d in graph.nodes.values() if any(is_pattern(i.source) for i in d.inputs.values())}
    topics: dict[str, str] = {}   # topic -> "<node_id>/<output>" source
    for decl in graph.nodes.values():
        if decl.id in classes and decl.id not in globbing:
            for topic, out in declared_topics(graph, decl, classes).items():
                topics[topic] = f"{decl.id}/{out}"
    errors = []
    for node_id in globbing:
        decl = graph.nodes[node_id]
        if node_id not in classes:
            continue
        if "*" not in classes[node_id].INPUTS:
            first = next(i for i in decl.inputs.values() if is_pattern(i.source))
            errors.append(GraphError(f"pattern source {first.source!r}: {decl.node} takes only its named inputs "
                                     f"({', '.join(classes[node_id].INPUTS) or 'none'}); patterns are for nodes "
                                     "that take any topic (rerun_sink, foxglove_bridge, bag_recorder)",
                                     file=decl.file, line=first.line, node_id=node_id, key=f"inputs.{first.name}"))
            decl.inputs = {n: i for n, i in decl.inputs.items() if not is_pattern(i.source)}
            continue
        errors += _expand_node(decl, topics)
    return errors


def _expand_node(decl: NodeDecl, topics: dict[str, str]) -> list[GraphError]:
    errors = []
    expanded: dict[str, InputDecl] = {n: i for n, i in decl.inputs.items() if not is_pattern(i.source)}
    taken = {i.source for i in expanded.values()}
    for inp in (i for i in decl.inputs.values() if is_pattern(i.source)):
        matches = [t for t in sorted(topics) if fnmatch.fnmatchcase(t, inp.source)
                   and not any(fnmatch.fnmatchcase(t, x) for x in inp.exclude)]
        if not matches:
            errors.append(GraphError(f"pattern {inp.source!r} matches no topic of the graph"
                                     f"{' after exclude ' + str(list(inp.exclude)) if inp.exclude else ''} "
                                     f"(topics: {', '.join(sorted(topics)) or 'none'})", file=decl.file,
                                     line=inp.line, node_id=decl.id, key=f"inputs.{inp.name}"))
            continue
        for topic in matches:
            if topics[topic] not in taken and topic not in expanded:
                expanded[topic] = replace(inp, name=topic, source=topics[topic], exclude=())
                taken.add(topics[topic])
    decl.inputs = expanded
    return errors
