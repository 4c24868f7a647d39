"""The tools' channel into a running node: introspection, run-time params, extra publishers.

Each node process binds a ROUTER at ``ctl_endpoint`` (``ipc://RUN_DIR/<index>.ctl``, inside the
private run directory) that its receiver thread serves; nodes never see it. A tool sends one
msgpack request and waits for one reply (:func:`request`):

``{"op": "info"}``
    pid, type, state, uptime, memory, params, inputs (queue, counters, rate), outputs (count, rate).
``{"op": "get"}``
    the current params and which of them are ``dynamic``.
``{"op": "set", "key": K, "value": V}``
    validated like ``probeless check`` (only params declared ``param(..., dynamic=True)``), then
    applied on the node's own thread between callbacks: ``node.params`` is replaced and
    ``node.on_param(key, value)`` is called. The reply comes once it is applied.
``{"op": "connect" | "disconnect", "topic": T, "lossless": E, "lossy": E2}``
    the inputs reading topic T also read (or stop reading) a tool's publisher (``topic pub``).

Replies are ``{"ok": True, ...}`` or ``{"ok": False, "error": "one line"}``.
"""

from __future__ import annotations

import dataclasses
import difflib
import os
from typing import Any

import msgpack
import zmq

from probeless.errors import ParamError, ProbelessError
from probeless.runtime.params import check_params, load_params


def ctl_endpoint(run_dir: Any, index: int) -> str:
    """Where node number ``index`` of a run serves tool requests."""
    return f"ipc://{run_dir}/{index}.ctl"


def request(endpoint: str, req: dict, timeout_s: float = 3.0, what: str = "the node") -> dict:
    """Send one request to a node's control endpoint and return its reply; ProbelessError on silence."""
    zctx = zmq.Context.instance()
    sock = zctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    try:
        sock.connect(endpoint)
        sock.send_multipart([b"", msgpack.packb(req)])
        if not sock.poll(int(timeout_s * 1000)):
            raise ProbelessError(f"{what} did not answer within {timeout_s:g} s (still starting, stopped, "
                                 f"or busy in a long callback)")
        parts = sock.recv_multipart()
        return msgpack.unpackb(parts[-1], raw=False)
    finally:
        sock.close(0)


def dynamic_keys(params_cls: type) -> list[str]:
    """Names of the params declared ``param(..., dynamic=True)``."""
    return [f.name for f in dataclasses.fields(params_cls) if f.metadata.get("dynamic")]


def params_dict(params: Any) -> dict[str, Any]:
    """A params dataclass as plain values (tuples become lists), for replies."""
    def plain(v: Any) -> Any:
        return [plain(x) for x in v] if isinstance(v, (tuple, list)) else v
    return {f.name: plain(getattr(params, f.name)) for f in dataclasses.fields(params)}


def updated_params(params_cls: type, current: Any, key: str, value: Any, node_id: str) -> Any:
    """``current`` with ``key`` set to ``value``, checked like ``probeless check``; ParamError otherwise."""
    names = [f.name for f in dataclasses.fields(params_cls)]
    dynamic = dynamic_keys(params_cls)
    if key not in names:
        close = difflib.get_close_matches(key, names, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ParamError(f"unknown parameter ({hint}known: {', '.join(names) or 'none'})", node_id=node_id, key=key)
    if key not in dynamic:
        raise ParamError(f"not a dynamic parameter: it is read once at start; restart the graph with a new "
                         f"value (dynamic: {', '.join(dynamic) or 'none'})", node_id=node_id, key=key)
    values = {**params_dict(current), key: value}
    errors = check_params(params_cls, values, node_id=node_id)
    if errors:
        raise errors[0]
    return load_params(params_cls, values, node_id=node_id)


def runtime_info(rt: Any) -> dict[str, Any]:
    """What ``probeless node info`` shows, from a NodeRuntime (runs on its receiver thread)."""
    with rt.cond:
        inputs = [{"name": q.name, "topic": rt._input_topic(q.name), "policy": q.policy,
                   "queue_size": q.queue_size, "queued": len(q.items), "received": q.received,
                   "dropped": q.dropped, "seq_gaps": q.seq_gaps, "invalid": q.invalid,
                   "rate_hz": rt.rates.get(("in", q.name))}
                  for q in rt.queues.values() if q.name != "__clock__"]
    for i in rt.spec["inputs"]:
        if "timer_period_ns" in i:
            inputs.append({"name": i["name"], "topic": f"timer ({1e9 / i['timer_period_ns']:g} Hz)",
                           "policy": "timer", "queue_size": 0, "queued": 0, "received": None, "dropped": 0,
                           "seq_gaps": 0, "invalid": 0, "rate_hz": None})
    pub = getattr(rt, "publisher", None)
    published = dict(pub.published) if pub is not None else {}
    latched, resent = (set(pub.latched), dict(pub.resent)) if pub is not None else (set(), {})
    outputs = [{"name": name, "topic": topic, "published": published.get(topic, 0),
                "rate_hz": rt.rates.get(("out", topic)), "latched": topic in latched,
                "resent_to_late_joiners": resent.get(topic, 0)} for name, topic in rt.topics.items()]
    params = rt.params
    return {"ok": True, "node_id": rt.node_id, "node": rt.spec["node"], "pid": os.getpid(), "state": rt.state,
            "uptime_s": rt.uptime_s(), "rss_bytes": rt.memory_last, "inputs": inputs, "outputs": outputs,
            "params": params_dict(params) if params is not None else None,
            "dynamic": dynamic_keys(rt.node_cls.Params), "timings": rt.last_timings}


def handle(rt: Any, req: Any, ident: bytes) -> dict | None:
    """Reply to one tool request (receiver thread); None when the reply comes later (``set``)."""
    op = req.get("op") if isinstance(req, dict) else None
    if op == "info":
        return runtime_info(rt)
    if op == "get":
        if rt.params is None:
            return {"ok": False, "error": f"node '{rt.node_id}' has not loaded its params yet"}
        return {"ok": True, "params": params_dict(rt.params), "dynamic": dynamic_keys(rt.node_cls.Params)}
    if op == "set":
        if rt.params is None:
            return {"ok": False, "error": f"node '{rt.node_id}' has not loaded its params yet"}
        try:
            new = updated_params(rt.node_cls.Params, rt.params, str(req.get("key")), req.get("value"), rt.node_id)
        except ParamError as exc:
            return {"ok": False, "error": exc.format()}
        with rt.cond:
            rt.param_updates.append((ident, str(req["key"]), new))
            rt.cond.notify()
        return None
    return {"ok": False, "error": f"unknown request {op!r}"}


def apply_updates(rt: Any) -> None:
    """Apply queued ``set`` requests on the node's thread and send their replies."""
    while True:
        with rt.cond:
            if not rt.param_updates:
                return
            ident, key, new = rt.param_updates.popleft()
        old = rt.node.params
        rt.node.params = new
        reply = {"ok": True, "key": key, "value": params_dict(new)[key]}
        hook = getattr(rt.node, "on_param", None)
        try:
            if hook is not None:
                hook(key, getattr(new, key))
        except (ProbelessError, ValueError) as exc:
            rt.node.params = old
            reply = {"ok": False, "error": f"node '{rt.node_id}': key '{key}': refused by the node: {exc}"}
        if reply["ok"]:
            rt.params = new
            rt.log.info("param %s set to %r", key, reply["value"])
        rt.receiver.reply_tool(ident, reply, rt.wake_tx)
