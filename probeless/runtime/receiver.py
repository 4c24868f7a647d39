"""The receiver thread of a node process: drains SUB sockets into input queues, talks to the launcher.

It applies each input's queue policy as messages arrive, so a slow callback never stalls
upstream unless the input asked for ``block``. It also owns the node's control socket (a DEALER
to the launcher's ROUTER): readiness, start, status snapshots for lockstep replay, and the
quiescence requests of a lockstep player. The node thread talks to it through ``send_control``.

A latched topic's last message, sent again by its publisher when a subscriber joins late, arrives with
the topic frame marked (``latching.LATCH_MARK``); an input takes it only while it has had no message
of that topic yet (it is the late joiner), so the subscribers that had it all along never see it twice.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable

import msgpack
import zmq

from probeless import wire
from probeless.errors import SchemaError
from probeless.runtime.latching import LATCH_MARK
from probeless.runtime.queues import InputQueue
from probeless.runtime.security import NodeCurve

log = logging.getLogger("probeless.receiver")
TOOL_PUBLISHER_PREFIX = "@tool/"   # publisher ids of tools (``topic pub``)
BLOCK_RECV_HWM = 4
DROP_RECV_HWM = 128   # lossy inputs: past this (plus the publisher's SEND_HWM) the publisher drops for us
EOS_MARK = object()


@dataclass(frozen=True)
class InputWire:
    """Where one input reads from."""

    name: str
    endpoint: str          # upstream publisher endpoint
    topic: str             # "<node_id>/<output>"
    type_name: str | None  # expected message type, None = any
    raw: bool = False      # deliver RawMessage (frames as received) instead of a decoded Message


@dataclass(frozen=True)
class RawMessage:
    """A message exactly as it crossed the wire, for recorders: no decoding beyond the envelope."""

    topic: str
    frames: list           # [meta, buffer0, ...] after the topic frame (zmq.Frame or bytes)
    type_name: str
    version: int
    publisher: str
    publish_ns: int        # publisher's wall clock at publish [ns]
    stamp_ns: int          # header.stamp_ns [ns]
    seq: int               # header.seq
    recv_ns: int           # this process's wall clock at receive [ns]


def hello_topic(node_id: str, input_name: str) -> bytes:
    """A subscription no message ever matches, telling the publisher which input subscribed.

    The readiness barrier waits for the hello of every wired input, so an extra subscriber (a
    topic tool, an attached recorder) can never stand in for a node that has not connected yet.
    """
    return b"\0hello/" + f"{node_id}/{input_name}".encode()


def peek_raw(topic: str, frames: list, recv_ns: int) -> RawMessage:
    """Envelope facts of raw frames ``[topic, meta, ...]``; SchemaError when the metadata is malformed."""
    try:
        meta = msgpack.unpackb(wire._view(frames[1]), raw=False)
        header = meta["fields"]["header"]
        return RawMessage(topic, list(frames[1:]), str(meta["type"]), int(meta["version"]),
                          str(meta["publisher"]), int(meta["publish_ns"]), int(header["stamp_ns"]),
                          int(header["seq"]), recv_ns)
    except (ValueError, TypeError, KeyError, IndexError) as exc:
        raise SchemaError(f"topic {topic!r}: malformed envelope: {exc}") from None


class Receiver(threading.Thread):
    """Drains SUB sockets into input queues; wakes the node thread through ``cond``."""

    def __init__(self, zctx: zmq.Context, wires: list[InputWire], queues: dict[str, InputQueue],
                 cond: threading.Condition, wake_endpoint: str, max_bytes: int = wire.MAX_MESSAGE_BYTES,
                 control: tuple[str, str] | None = None, status: Callable[[], dict] | None = None,
                 node_id: str = "", curve: NodeCurve | None = None,
                 tools: tuple[str, Callable[[Any, bytes], dict | None]] | None = None):
        super().__init__(name="probeless-receiver", daemon=True)
        self.cond, self.queues, self.max_bytes = cond, queues, max_bytes
        self.stopping = False
        self.eos_seen = False  # set once any input has reached end of stream
        self.arrivals = 0
        self.started = threading.Event()   # launcher said start
        self.quiet = threading.Event()     # launcher confirmed quiescence (lockstep)
        self.status = status or (lambda: {})
        self.outbox: deque[list[bytes]] = deque()
        self.tool_outbox: deque[tuple[bytes, dict]] = deque()
        self.wake = zctx.socket(zmq.PAIR)
        self.wake.bind(wake_endpoint)
        self.control = None
        if control is not None:
            self.control = zctx.socket(zmq.DEALER)
            self.control.setsockopt(zmq.IDENTITY, control[1].encode())
            self.control.setsockopt(zmq.LINGER, 0)
            self.control.connect(control[0])
        self.tools, self.tool_handler = None, None
        if tools is not None:  # the tools' channel (control.py): introspection, params, extra publishers
            self.tools = zctx.socket(zmq.ROUTER)
            self.tools.setsockopt(zmq.LINGER, 0)
            self.tools.bind(tools[0])
            self.tool_handler = tools[1]
        self.socks: dict[zmq.Socket, InputWire] = {}
        for w in wires:
            s = zctx.socket(zmq.SUB)
            s.setsockopt(zmq.RCVHWM, BLOCK_RECV_HWM if queues[w.name].policy == "block" else DROP_RECV_HWM)
            s.setsockopt(zmq.LINGER, 0)
            s.setsockopt(zmq.MAXMSGSIZE, max_bytes)  # refuse oversized frames before allocating them
            if "[" in w.endpoint:
                s.setsockopt(zmq.IPV6, 1)  # tcp://[::1]:PORT
            if curve is not None:
                curve.client(s, w.endpoint)  # CURVE client on tcp (security.py)
            s.connect(w.endpoint)
            s.setsockopt(zmq.SUBSCRIBE, w.topic.encode())
            s.setsockopt(zmq.SUBSCRIBE, hello_topic(node_id, w.name))  # names this subscriber to the barrier
            self.socks[s] = w
        self.topic_bytes = {s: w.topic.encode() for s, w in self.socks.items()}
        self.latched_bytes = {s: t + LATCH_MARK for s, t in self.topic_bytes.items()}
        self.heard: set[zmq.Socket] = set()   # inputs that have had a message (a latched re-send is not for them)
        self.pending: dict[zmq.Socket, tuple] = {}

    def send_control(self, *parts: bytes, wake_tx: zmq.Socket) -> None:
        """Queue a message to the launcher (called from the node thread)."""
        self.outbox.append(list(parts))
        wake_tx.send(b"")

    def reply_tool(self, ident: bytes, reply: dict, wake_tx: zmq.Socket) -> None:
        """Queue a late reply to a tool request (called from the node thread)."""
        self.tool_outbox.append((ident, reply))
        wake_tx.send(b"")

    def run(self) -> None:
        poller = zmq.Poller()
        poller.register(self.wake, zmq.POLLIN)
        if self.control is not None:
            poller.register(self.control, zmq.POLLIN)
        if self.tools is not None:
            poller.register(self.tools, zmq.POLLIN)
        for s in self.socks:
            poller.register(s, zmq.POLLIN)
        while not self.stopping:
            for sock, _ in poller.poll(500):
                if sock is self.wake:
                    self.wake.recv()
                    self._flush_outbox()
                    self._retry_pending(poller)
                elif sock is self.control:
                    self._on_control(self.control.recv_multipart())
                elif sock is self.tools:
                    self._on_tool(self.tools.recv_multipart(), poller)
                elif sock not in self.pending:
                    self._receive(sock, poller)
        extra = [s for s in (self.control, self.tools) if s is not None]
        for s in list(self.socks) + [self.wake] + extra:
            s.close(0)

    def _flush_outbox(self) -> None:
        while self.outbox:
            parts = self.outbox.popleft()
            if self.control is not None:
                self.control.send_multipart(parts)
        while self.tool_outbox:
            ident, reply = self.tool_outbox.popleft()
            self._reply_tool(ident, reply)

    def _reply_tool(self, ident: bytes, reply: dict) -> None:
        try:
            self.tools.send_multipart([ident, b"", msgpack.packb(reply, default=str)])
        except zmq.ZMQError:
            pass  # the tool went away

    def _on_tool(self, parts: list[bytes], poller: zmq.Poller) -> None:
        """One tool request ``[identity, b"", msgpack]``; replies now unless the handler defers it."""
        ident = parts[0]
        try:
            req = msgpack.unpackb(parts[-1], raw=False)
        except Exception:
            self._reply_tool(ident, {"ok": False, "error": "malformed request"})
            return
        if isinstance(req, dict) and req.get("op") in ("connect", "disconnect"):
            reply = self._connect_tool(req, poller)
        else:
            try:
                reply = self.tool_handler(req, ident)
            except Exception as exc:  # a tool must never take the node down
                reply = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        if reply is not None:
            self._reply_tool(ident, reply)

    def _connect_tool(self, req: dict, poller: zmq.Poller) -> dict:
        """Inputs reading ``topic`` also read a tool's publisher (``topic pub``), or stop doing so."""
        names = []
        for sock, w in list(self.socks.items()):
            if w.topic != req.get("topic"):
                continue
            if req["op"] == "disconnect" and sock not in self.pending:
                self._receive(sock, poller)  # what already arrived from the tool is kept, not cut off
            if sock not in self.socks:
                continue  # it reached end of stream meanwhile
            endpoint = str(req["lossless"] if self.queues[w.name].policy == "block" else req["lossy"])
            try:
                (sock.connect if req["op"] == "connect" else sock.disconnect)(endpoint)
            except zmq.ZMQError as exc:
                if req["op"] == "connect":
                    return {"ok": False, "error": f"cannot connect input {w.name!r} to {endpoint}: {exc}"}
            names.append(w.name)
        return {"ok": True, "inputs": names}

    def _on_control(self, parts: list[bytes]) -> None:
        kind = parts[0]
        if kind == b"start":
            self.started.set()
        elif kind == b"status":
            self.control.send_multipart([b"status", parts[1], msgpack.packb(self.status())])
        elif kind == b"quiet":
            self.quiet.set()

    def _receive(self, sock: zmq.Socket, poller: zmq.Poller) -> None:
        w = self.socks[sock]
        topic = self.topic_bytes[sock]
        while sock not in self.pending and sock.get(zmq.EVENTS) & zmq.POLLIN:
            frames = sock.recv_multipart(copy=False)
            head = frames[0].bytes
            if head != topic and (head != self.latched_bytes[sock] or sock in self.heard):
                continue  # prefix match of another topic, or a latched message re-sent for another (late) joiner
            self.heard.add(sock)
            if wire.is_eos(frames):
                self._push(w.name, (EOS_MARK, None))
                poller.unregister(sock)
                del self.socks[sock]
                sock.close(0)  # tells the publisher this subscriber has everything
                return
            try:
                item = self._item(w, frames)
            except SchemaError as exc:
                with self.cond:
                    self.queues[w.name].invalid += 1
                log.error("input %r (topic %s): discarded invalid message: %s", w.name, w.topic, exc)
                continue
            if not self._push(w.name, item):
                self.pending[sock] = item
                poller.unregister(sock)

    def _item(self, w: InputWire, frames: list) -> tuple[Any, int, int]:
        """(message, seq, payload bytes) of received frames."""
        nbytes = sum(len(f) for f in frames)
        if w.raw:
            raw = peek_raw(w.topic, frames, time.time_ns())
            return raw, raw.seq, nbytes
        _, env, msg = wire.decode(frames, expected=w.type_name, max_bytes=self.max_bytes)
        from_tool = env.publisher.startswith(TOOL_PUBLISHER_PREFIX)  # `topic pub`: its own seq, not counted
        return msg, None if from_tool else msg.header.seq, nbytes

    def _push(self, name: str, item: tuple) -> bool:
        with self.cond:
            q = self.queues[name]
            if item[0] is EOS_MARK:
                q.eos = True
                self.eos_seen = True
            else:
                self.arrivals += 1
                if not q.push(self.arrivals, *item):
                    return False
            self.cond.notify()
        return True

    def _retry_pending(self, poller: zmq.Poller) -> None:
        for sock, item in list(self.pending.items()):
            if self._push(self.socks[sock].name, item):
                del self.pending[sock]
                poller.register(sock, zmq.POLLIN)
                self._receive(sock, poller)

    def stop(self, wake_tx: zmq.Socket) -> None:
        self.stopping = True
        try:
            # never block: the thread may already have seen `stopping` and closed its end, and a PAIR send with no
            # peer waits forever (a node then hung at exit); it polls every 500 ms and sees the flag anyway
            wake_tx.send(b"", zmq.NOBLOCK)
        except zmq.Again:
            pass
