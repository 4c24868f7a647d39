"""``probeless topic info``: type, publisher, subscribers and their counters from NodeStatus."""

from __future__ import annotations

import sys
import time
from typing import IO, Any

from probeless.runtime.security import tool_curve
from probeless.topics.catalog import find_topic, graph_topics
from probeless.topics.discovery import RunningGraph
from probeless.topics.reader import TopicReader, wait_for_start


def topic_info(graph: RunningGraph, topic_name: str, *, timeout: float = 2.5) -> dict[str, Any]:
    """Type, publisher and subscribers of a topic, with each subscriber's counters for it read
    from its NodeStatus (up to ``timeout`` seconds of listening to the nodes' diagnostics)."""
    topic = find_topic(graph, topic_name)
    nodes = graph.plan["nodes"]
    watch = [topic.publisher] + [s.node for s in topic.subscribers]
    diag = {f"{n}/diagnostics": nodes[n]["endpoint"] for n in dict.fromkeys(watch)}
    statuses: dict[str, Any] = {}
    deadline = time.monotonic() + timeout
    topics = graph_topics(graph)
    if any(topics[t].expected for t in diag if t in topics):
        wait_for_start(graph, timeout=timeout)
    with TopicReader(diag.items(), policy="latest", queue_size=1, curve=tool_curve(graph.plan)) as reader:
        while len(statuses) < len(diag) and time.monotonic() < deadline:
            for name, _, msg in reader.take(min(0.1, max(0.0, deadline - time.monotonic()))):
                statuses[name.rpartition("/")[0]] = msg
            if reader.ended:
                break
    pub_status = statuses.get(topic.publisher)
    published = None
    if pub_status is not None:
        for entry in pub_status.published:
            t, _, n = entry.rpartition("=")
            if t == topic.name and n.isdigit():
                published = int(n)
    subs = []
    for s in topic.subscribers:
        st = statuses.get(s.node)
        counters = None
        if st is not None:
            c = next((c for c in st.inputs if c.topic == topic.name and c.name == s.input), None)
            c = c or next((c for c in st.inputs if c.topic == topic.name), None)
            if c is not None:
                counters = {"received": c.received, "dropped": c.dropped, "seq_gaps": c.seq_gaps,
                            "queued": c.queued, "invalid": c.invalid, "queued_bytes": c.queued_bytes,
                            "publisher_restarts": c.publisher_restarts}
        subs.append({"node": s.node, "input": s.input, "policy": s.policy, "queue_size": s.queue_size,
                     "node_state": st.state if st is not None else None, "counters": counters})
    return {"topic": topic.name, "type": topic.type_name, "declared": topic.declared,
            "publisher": {"node": topic.publisher, "node_type": topic.node_type, "endpoint": topic.endpoint,
                          "state": pub_status.state if pub_status is not None else None, "published": published},
            "subscribers": subs, "timeout": timeout}


def print_info(info: dict[str, Any], out: IO[str] | None = None) -> None:
    out = out or sys.stdout
    p = info["publisher"]
    print(f"topic: {info['topic']}", file=out)
    print(f"type: {info['type'] or '? (unknown)'}", file=out)
    extra = "" if p["state"] is None else f"  state {p['state']}"
    extra += "" if p["published"] is None else f"  published {p['published']}"
    if p["state"] is None:
        extra += f"  (no diagnostics within {info['timeout']:g} s)"
    print(f"publisher: {p['node']} ({p['node_type']}) at {p['endpoint']}{extra}", file=out)
    print(f"subscribers: {len(info['subscribers'])}", file=out)
    for s in info["subscribers"]:
        line = f"  {s['node']}.{s['input']}  policy {s['policy']}  queue_size {s['queue_size']}"
        c = s["counters"]
        if c is not None:
            line += (f"  received {c['received']}  dropped {c['dropped']}  seq_gaps {c['seq_gaps']}"
                     f"  queued {c['queued']} ({c['queued_bytes']} B)  invalid {c['invalid']}")
            if c["publisher_restarts"]:
                line += f"  publisher_restarts {c['publisher_restarts']}"
        elif s["node_state"] is None:
            line += f"  (no diagnostics within {info['timeout']:g} s)"
        else:
            line += "  (no counters for this topic in its diagnostics)"
        print(line, file=out)
