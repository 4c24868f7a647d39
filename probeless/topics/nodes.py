"""``probeless node list|info``, ``probeless param get|set`` and ``probeless runs``: a running graph's nodes.

Each node answers on its control endpoint (:mod:`probeless.runtime.control`), served by the
runtime's receiver thread, so a node busy in a callback still answers ``info`` and ``get``; a
``set`` is applied between two callbacks and answered then.
"""

from __future__ import annotations

import difflib
import sys
import time
from typing import IO, Any

from probeless.errors import ProbelessError
from probeless.runtime.control import request
from probeless.runtime.runs import RunningGraph, running_graphs


def _node(graph: RunningGraph, node_id: str) -> dict:
    nodes = graph.plan["nodes"]
    if node_id not in nodes:
        close = difflib.get_close_matches(node_id, list(nodes), n=3)
        hint = f"did you mean {', '.join(close)}?" if close else f"nodes: {', '.join(nodes)}"
        raise ProbelessError(f"no node {node_id!r} in {graph.plan.get('file', 'the graph')} ({hint})")
    node = nodes[node_id]
    if not node.get("ctl_endpoint"):
        raise ProbelessError(f"node {node_id!r} has no control endpoint (its graph was started by an older "
                             f"probeless)")
    return node


def _ask(graph: RunningGraph, node_id: str, req: dict, timeout_s: float = 3.0) -> dict:
    reply = request(_node(graph, node_id)["ctl_endpoint"], req, timeout_s, what=f"node {node_id!r}")
    if not reply.get("ok"):
        raise ProbelessError(reply.get("error", "request refused"))
    return reply


def node_infos(graph: RunningGraph, timeout_s: float = 1.5) -> dict[str, dict | None]:
    """``info`` of every node (None for a node that did not answer: starting, ended or hung)."""
    from concurrent.futures import ThreadPoolExecutor

    def one(node_id: str) -> dict | None:
        try:
            return _ask(graph, node_id, {"op": "info"}, timeout_s)
        except ProbelessError:
            return None
    ids = list(graph.plan["nodes"])
    with ThreadPoolExecutor(max_workers=min(16, max(1, len(ids)))) as pool:  # a hung node costs one timeout
        return dict(zip(ids, pool.map(one, ids)))


def _rate(hz: float | None) -> str:
    return "-" if hz is None else f"{hz:.1f}"


def list_nodes(graph: RunningGraph, out: IO[str] | None = None) -> dict[str, dict | None]:
    """One line per node: id, type, pid, state, output rate, queued and dropped input messages."""
    out = out or sys.stdout
    infos = node_infos(graph)
    rows = [("NODE", "TYPE", "PID", "STATE", "OUT HZ", "QUEUED", "DROPPED")]
    for node_id, spec in graph.plan["nodes"].items():
        i = infos[node_id]
        if i is None:
            rows.append((node_id, spec["node"], "-", "no answer", "-", "-", "-"))
            continue
        rates = [o["rate_hz"] for o in i["outputs"] if o["rate_hz"] is not None]
        rows.append((node_id, i["node"], str(i["pid"]), i["state"], _rate(max(rates)) if rates else "-",
                     str(sum(x["queued"] for x in i["inputs"])), str(sum(x["dropped"] for x in i["inputs"]))))
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    for r in rows:
        print("  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip(), file=out)
    return infos


def print_node_info(info: dict, out: IO[str] | None = None) -> None:
    """``probeless node info NODE``: everything the node reports about itself."""
    out = out or sys.stdout
    p = lambda text="": print(text, file=out)  # noqa: E731
    p(f"node {info['node_id']}  ({info['node']})")
    p(f"  pid {info['pid']}  state {info['state']}  uptime {info['uptime_s']:.1f} s  "
      f"memory {info['rss_bytes'] / 2**20:.0f} MiB")
    p("inputs:" if info["inputs"] else "inputs: none")
    for i in info["inputs"]:
        if i["policy"] == "timer":
            p(f"  {i['name']}: {i['topic']}")
            continue
        p(f"  {i['name']} <- {i['topic']}  {_rate(i['rate_hz'])} Hz  queue {i['queued']}/{i['queue_size']} "
          f"({i['policy']})  received {i['received']}  dropped {i['dropped']}  seq gaps {i['seq_gaps']}"
          + (f"  invalid {i['invalid']}" if i["invalid"] else ""))
    p("outputs:" if info["outputs"] else "outputs: none")
    for o in info["outputs"]:
        p(f"  {o['name']} -> {o['topic']}  {_rate(o['rate_hz'])} Hz  published {o['published']}")
    params = info.get("params") or {}
    p("params:" if params else "params: none")
    for k, v in params.items():
        p(f"  {k}: {v!r}{'  (dynamic)' if k in info['dynamic'] else ''}")
    if info.get("timings"):
        p("callbacks (last second):")
        for t in info["timings"]:
            p(f"  {t['name']}: {t['count']} calls, p50 {t['p50_ms']:.2f} ms, max {t['max_ms']:.2f} ms")


def node_info(graph: RunningGraph, node_id: str, timeout_s: float = 3.0) -> dict:
    return _ask(graph, node_id, {"op": "info"}, timeout_s)


def param_get(graph: RunningGraph, node_id: str, key: str | None = None) -> dict[str, Any]:
    """The node's current params (all, or just ``key``), and which are dynamic."""
    reply = _ask(graph, node_id, {"op": "get"})
    params = reply["params"]
    if key is not None and key not in params:
        close = difflib.get_close_matches(key, list(params), n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ProbelessError(f"node '{node_id}': key '{key}': unknown parameter ({hint}known: "
                             f"{', '.join(params) or 'none'})")
    return {"params": params if key is None else {key: params[key]}, "dynamic": reply["dynamic"]}


def param_set(graph: RunningGraph, node_id: str, key: str, value: Any, timeout_s: float = 5.0) -> Any:
    """Set a dynamic param; returns the value the node now holds (converted: ints to floats...)."""
    return _ask(graph, node_id, {"op": "set", "key": key, "value": value}, timeout_s)["value"]


def print_runs(out: IO[str] | None = None) -> list[RunningGraph]:
    """``probeless runs``: one line per running graph, its run id first (what ``--graph`` takes)."""
    out = out or sys.stdout
    graphs = running_graphs()
    if not graphs:
        print("no running graphs", file=out)
    rows = [("RUN_ID", "GRAPH", "PID", "STARTED", "NODES")]
    for g in graphs:
        started = time.strftime("%H:%M:%S", time.localtime(g.started_ns / 1e9)) if g.started_ns else "?"
        rows.append((g.run_id, str(g.plan.get("file", "?")), str(g.launcher_pid), started,
                     str(len(g.plan["nodes"]))))
    if graphs:
        widths = [max(len(r[c]) for r in rows) for c in range(5)]
        for r in rows:
            print("  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip(), file=out)
    return graphs
