"""``probeless topic pub TOPIC TYPE YAML [--rate HZ]``: publish messages into a running graph's topic.

The tool binds a publisher of its own (in a private folder beside the run directories) and asks
each node whose input reads TOPIC to also read that publisher (control channel, ``connect``); on
exit it asks them to stop (``disconnect``). Subscribers then receive the tool's messages next to
the graph's own, as with ``ros2 topic pub``. The tool's sequence numbers are not counted in the
inputs' gap counters.

The YAML is a mapping of the message's fields (``header`` may be left out: it is stamped now);
arrays are given as (nested) lists and take the first dtype the type allows.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import time
from typing import IO, Any

import numpy as np

from probeless.errors import ProbelessError, SchemaError
from probeless.messages.base import Message, lookup, schema_of
from probeless.messages.header import Header
from probeless.runtime.control import request
from probeless.runtime.receiver import TOOL_PUBLISHER_PREFIX
from probeless.runtime.runs import RunningGraph, runs_base
from probeless.runtime.transport import Publisher, lossy_endpoint
from probeless.topics.catalog import find_topic


def _yaml_name(value: Any) -> str:
    """The YAML word for a value's kind (never a Python class name)."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, (list, tuple)):
        return "a list"
    return "null" if value is None else "a value"


def build_message(cls: type, doc: Any, where: str = "", stamp_ns: int | None = None) -> Any:
    """A message or struct ``cls`` from a YAML mapping; ProbelessError naming the field at fault."""
    where = where or cls.__name__
    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise ProbelessError(f"{where}: expected a mapping of fields, got {_yaml_name(doc)}")
    specs = {s.name: s for s in schema_of(cls)}
    unknown = [k for k in doc if k not in specs]
    if unknown:
        raise ProbelessError(f"{where}: unknown field(s) {', '.join(map(str, unknown))} "
                             f"(fields: {', '.join(specs)})")
    defaults = {f.name for f in dataclasses.fields(cls)
                if f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING}
    kwargs = {}
    for name, spec in specs.items():
        if name not in doc:
            if spec.kind == "struct" and spec.struct is Header:
                kwargs[name] = Header(stamp_ns if stamp_ns is not None else time.time_ns())
            elif name not in defaults:
                raise ProbelessError(f"{where}: missing field '{name}'")
            continue
        kwargs[name] = _value(spec, doc[name], f"{where}.{name}", stamp_ns)
    try:
        return cls(**kwargs)
    except SchemaError as exc:
        raise ProbelessError(str(exc)) from None


def _value(spec: Any, value: Any, where: str, stamp_ns: int | None) -> Any:
    if spec.kind == "struct":
        if spec.struct is Header and isinstance(value, dict) and "stamp_ns" not in value:
            value = {**value, "stamp_ns": stamp_ns if stamp_ns is not None else time.time_ns()}
        return build_message(spec.struct, value, where, stamp_ns)
    if spec.kind == "array":
        try:
            return np.asarray(value, dtype=spec.array.dtypes[0])
        except (TypeError, ValueError) as exc:
            raise ProbelessError(f"{where}: not an array of {spec.array.dtypes[0]}: {exc}") from None
    if spec.kind == "tuple":
        if not isinstance(value, list):
            raise ProbelessError(f"{where}: expected a list, got {_yaml_name(value)}")
        return tuple(_value(spec.item, v, f"{where}[{i}]", stamp_ns) for i, v in enumerate(value))
    return value


def publish(graph: RunningGraph, topic_name: str, type_name: str, doc: Any, *, rate_hz: float | None = None,
            count: int | None = None, wait_s: float = 10.0, err: IO[str] | None = None,
            out: IO[str] | None = None) -> int:
    """Publish ``doc`` as a ``type_name`` message on ``topic_name`` once, or at ``rate_hz`` (until ``count``
    messages or Ctrl-C). Returns the number of messages sent."""
    import sys

    err, out = err or sys.stderr, out or sys.stdout
    topic = find_topic(graph, topic_name)
    try:
        cls: type[Message] = lookup(type_name)
    except SchemaError:
        raise ProbelessError(f"unknown message type {type_name!r}") from None
    if topic.type_name and topic.type_name != type_name:
        raise ProbelessError(f"topic {topic.name} carries {topic.type_name}, not {type_name}")
    build_message(cls, doc)  # check the YAML before touching the graph
    if not topic.subscribers:
        print(f"note: no node of the graph reads {topic.name}; nothing will receive these messages", file=err)
    total = 1 if rate_hz is None and count is None else count
    folder = tempfile.mkdtemp(prefix="pub-", dir=runs_base())
    endpoint = f"ipc://{folder}/pub.pub"
    import zmq

    zctx = zmq.Context()
    pubr = Publisher(zctx, endpoint, f"{TOOL_PUBLISHER_PREFIX}topic-pub/{os.getpid()}")
    req = {"topic": topic.name, "lossless": endpoint, "lossy": lossy_endpoint(endpoint)}
    nodes = sorted({s.node for s in topic.subscribers})
    sent = 0
    try:
        for node in nodes:
            reply = request(graph.plan["nodes"][node]["ctl_endpoint"], {"op": "connect", **req},
                            what=f"node {node!r}")
            if not reply.get("ok"):
                raise ProbelessError(reply.get("error", f"node {node!r} refused the connection"))
        deadline = time.monotonic() + wait_s
        while pubr.subscriptions[topic.name] < len(nodes) and time.monotonic() < deadline:
            pubr.poll_subscriptions(50)
        if pubr.subscriptions[topic.name] < len(nodes):
            print(f"warning: only {pubr.subscriptions[topic.name]} of {len(nodes)} subscriber(s) connected "
                  f"within {wait_s:g} s", file=err)
        period = 1.0 / rate_hz if rate_hz else 0.0
        next_t = time.monotonic()
        while total is None or sent < total:
            msg = build_message(cls, doc)
            pubr.publish(topic.name, msg, lambda: False)
            sent += 1
            print(f"published {type_name} on {topic.name} (#{sent})", file=out, flush=True)
            if total is not None and sent >= total:
                break
            next_t += period
            time.sleep(max(0.0, next_t - time.monotonic()))
    except KeyboardInterrupt:
        pass
    finally:
        time.sleep(0.3)  # let the last message reach the subscribers' sockets; they read it before disconnecting
        for node in nodes:
            try:
                request(graph.plan["nodes"][node]["ctl_endpoint"], {"op": "disconnect", **req}, timeout_s=1.0)
            except ProbelessError:
                pass
        pubr.close()
        zctx.term()
        shutil.rmtree(folder, ignore_errors=True)
    return sent
