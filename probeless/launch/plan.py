"""The resolved run plan handed to node processes: endpoints, wiring, subscriber counts."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path
from typing import Any

from probeless.launch.graph import Graph
from probeless.launch.secure import curve_plan
from probeless.launch.validate import host_endpoint, split_source
from probeless.runtime.control import ctl_endpoint
from probeless.runtime.latching import is_latched
from probeless.runtime.node import output_type
from probeless.runtime.runs import runs_base
from probeless.runtime.transport import endpoint_for_policy, lossy_endpoint


def _output(decl, name: str) -> dict[str, Any]:
    out = {"topic": decl.topics.get(name, f"{decl.id}/{name}")}
    if name in decl.output_types:
        out["type_name"] = decl.output_types[name]
    return out


def new_run_dir() -> Path:
    """A fresh private directory for this run's ipc sockets and graph spec (short: ipc paths are limited)."""
    base = runs_base()
    base.mkdir(mode=0o700, parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=time.strftime("%H%M%S-"), dir=base))


def build_plan(graph: Graph, run_dir: Path, clock_node: str | None = None) -> dict[str, Any]:
    """JSON-serialisable plan of a validated graph (``graph.node_classes`` filled by validate).

    ``clock_node`` (a replay's player) publishes ``<clock_node>/clock``; every other node follows it.
    """
    endpoints = {}
    for index, decl in enumerate(graph.nodes.values()):
        endpoints[decl.id] = host_endpoint(graph, decl) or f"ipc://{run_dir}/{index}.pub"
    subscribers: dict[str, list[list[str]]] = {}  # topic -> [[node_id, input], ...]
    nodes = {}
    for index, decl in enumerate(graph.nodes.values()):
        cls = graph.node_classes[decl.id]
        inputs = []
        for inp in decl.inputs.values():
            entry = {"name": inp.name, "policy": inp.policy, "queue_size": inp.queue_size, "feedback": inp.feedback}
            if inp.max_bytes is not None:
                entry["max_bytes"] = inp.max_bytes
            if inp.timer_period_ns is not None:
                entry["timer_period_ns"] = inp.timer_period_ns
            elif inp.resolved is not None:  # external: a topic of another running graph (launch/external.py)
                ext = inp.resolved
                entry.update(topic=ext["topic"], source_node=None, output=None, external=ext["run_id"],
                             endpoint=endpoint_for_policy(ext["endpoint"], inp.policy), type_name=ext["type_name"])
            else:
                src_id, out = split_source(graph, inp.source)
                topic = graph.nodes[src_id].topics.get(out, f"{src_id}/{out}")
                _, typ = output_type(graph.node_classes[src_id], out)
                recorded_type = graph.nodes[src_id].output_types.get(out)
                entry.update(topic=topic, source_node=src_id, output=out,
                             endpoint=endpoint_for_policy(endpoints[src_id], inp.policy),
                             type_name=typ.TYPE_NAME if typ is not None else recorded_type)
                subscribers.setdefault(topic, []).append([decl.id, inp.name])
            inputs.append(entry)
        names = decl.outputs if decl.outputs is not None else [o for o in cls.OUTPUTS if not o.endswith("/*")]
        nodes[decl.id] = {"id": decl.id, "index": index, "node": decl.node, "params": decl.params,
                          "file": decl.file, "line": decl.line, "endpoint": endpoints[decl.id],
                          "ctl_endpoint": ctl_endpoint(run_dir, index),
                          "lossy_endpoint": lossy_endpoint(endpoints[decl.id]),
                          "host": decl.host, "inputs": inputs, "restart": decl.restart,
                          "max_restarts": decl.max_restarts, "restart_backoff_s": decl.restart_backoff_s,
                          "latched": dict(decl.latched),
                          "outputs": {o: _output(decl, o) for o in names}}
    for node in nodes.values():
        for inp in node["inputs"]:
            if "topic" in inp and inp.get("source_node") in nodes:
                node_out = nodes[inp["source_node"]]["outputs"].setdefault(inp["output"], {"topic": inp["topic"]})
                node_out["subscribers"] = len(subscribers[inp["topic"]])
                node_out["subscriber_ids"] = subscribers[inp["topic"]]
    if clock_node is not None:
        clock_topic = f"{clock_node}/clock"
        followers = [n for n in nodes.values() if n["id"] != clock_node]
        for node in followers:
            node["clock"] = {"topic": clock_topic, "endpoint": endpoints[clock_node], "source_node": clock_node}
        nodes[clock_node]["outputs"]["clock"] = {"topic": clock_topic, "subscribers": len(followers),
                                                 "subscriber_ids": [[n["id"], "__clock__"] for n in followers]}
    for node in nodes.values():
        for name, out in node["outputs"].items():
            out.setdefault("subscribers", 0)
            out["latched"] = is_latched(name, node["latched"])  # runtime/latching.py
    return {"file": graph.file, "file_abs": str(Path(graph.file).resolve()), "run_id": Path(run_dir).name,
            "args": graph.args, "run_dir": str(run_dir), "launcher_pid": os.getpid(),
            "started_ns": time.time_ns(),
            "control": f"ipc://{run_dir}/control", "nodes": nodes, "curve": curve_plan(graph, nodes)}
