"""Sockets of one node process: an XPUB publisher and a receiver thread feeding the input queues.

The publisher is an XPUB with NODROP, so a send waits (instead of silently dropping) when a
subscriber's pipe is full; only ``block`` inputs ever let their pipe fill, which is exactly the
backpressure that policy asks for. XPUB also reports each subscription, which is what the
readiness barrier counts. The receiver thread drains every SUB socket continuously, decodes, and
applies each input's queue policy, so a slow callback never stalls upstream for other policies.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from dataclasses import dataclass
from typing import Callable

import zmq

from probeless import wire
from probeless.errors import SchemaError, TransportError
from probeless.messages.base import Message
from probeless.runtime.queues import InputQueue

log = logging.getLogger("probeless.transport")
SEND_HWM = 16
BLOCK_RECV_HWM = 4
DROP_RECV_HWM = 1000
EOS_MARK = object()


class Publisher:
    """One node's output socket: publishes messages with per-topic seq, counts subscriptions."""

    def __init__(self, zctx: zmq.Context, endpoint: str, publisher_id: str):
        self.publisher_id = publisher_id
        self.sock = zctx.socket(zmq.XPUB)
        self.sock.setsockopt(zmq.XPUB_NODROP, 1)
        self.sock.setsockopt(zmq.XPUB_VERBOSER, 1)   # every subscribe and unsubscribe, even duplicates
        self.sock.setsockopt(zmq.SNDHWM, SEND_HWM)
        self.sock.setsockopt(zmq.SNDTIMEO, 100)
        self.sock.setsockopt(zmq.LINGER, 2000)
        try:
            self.sock.bind(endpoint)
        except zmq.ZMQError as exc:
            raise TransportError(f"{publisher_id}: cannot bind {endpoint}: {exc}") from None
        self.subscriptions: Counter[str] = Counter()
        self.seq: Counter[str] = Counter()
        self.published: Counter[str] = Counter()

    def poll_subscriptions(self, timeout_ms: int = 0) -> None:
        """Read pending (un)subscribe notifications into ``subscriptions``."""
        while self.sock.poll(timeout_ms, zmq.POLLIN):
            event = self.sock.recv()
            if event:
                self.subscriptions[event[1:].decode(errors="replace")] += 1 if event[0] == 1 else -1
            timeout_ms = 0

    def publish(self, topic: str, msg: Message, should_stop: Callable[[], bool]) -> None:
        """Send ``msg`` on ``topic`` with the next seq; waits under backpressure until sent or stopped."""
        seq = self.seq[topic]
        self.seq[topic] = seq + 1
        frames = wire.encode(topic, msg, self.publisher_id, time.time_ns(), seq=seq)
        self._send(frames, should_stop)
        self.published[topic] += 1

    def send_eos(self, topic: str, should_stop: Callable[[], bool]) -> None:
        self._send([topic.encode(), wire.EOS], should_stop)

    def wait_drained(self, topics: list[str], should_stop: Callable[[], bool],
                     note: Callable[[str], None]) -> bool:
        """After end-of-stream, wait until every subscriber of ``topics`` has unsubscribed.

        A subscriber closes its socket once it has read the end-of-stream marker, so everything
        sent before it is in the subscriber's memory. Exiting earlier would lose what still sits in
        socket buffers: libzmq drops a peer's unread data when the connection goes away.
        """
        last_note = time.monotonic()
        while not should_stop():
            self.poll_subscriptions(50)
            busy = [t for t in topics if self.subscriptions[t] > 0]
            if not busy:
                return True
            if time.monotonic() - last_note > 5:
                last_note = time.monotonic()
                note(", ".join(f"{t} ({self.subscriptions[t]})" for t in busy))
        return False

    def _send(self, frames: list, should_stop: Callable[[], bool]) -> None:
        last = len(frames) - 1
        first = True
        for i, frame in enumerate(frames):
            flags = zmq.SNDMORE if i < last else 0
            big = getattr(frame, "nbytes", len(frame)) >= wire.ZERO_COPY_BYTES
            while True:
                try:
                    self.sock.send(frame, flags, copy=not big)
                    break
                except zmq.Again:
                    # only the first frame waits: HWM counts whole messages
                    if not first or should_stop():
                        raise TransportError("publish interrupted by shutdown") from None
            first = False

    def close(self) -> None:
        self.sock.close()


@dataclass(frozen=True)
class InputWire:
    """Where one input reads from."""

    name: str
    endpoint: str          # upstream publisher endpoint
    topic: str             # "<node_id>/<output>"
    type_name: str | None  # expected message type, None = any


class Receiver(threading.Thread):
    """Drains SUB sockets into input queues; wakes the node thread through ``cond``."""

    def __init__(self, zctx: zmq.Context, wires: list[InputWire], queues: dict[str, InputQueue],
                 cond: threading.Condition, wake_endpoint: str, max_bytes: int = wire.MAX_MESSAGE_BYTES):
        super().__init__(name="probeless-receiver", daemon=True)
        self.cond = cond
        self.queues = queues
        self.max_bytes = max_bytes
        self.stopping = False
        self.eos_seen = False  # set once any input has reached end of stream
        self.arrivals = 0
        self.wake = zctx.socket(zmq.PAIR)
        self.wake.bind(wake_endpoint)
        self.socks: dict[zmq.Socket, InputWire] = {}
        for w in wires:
            s = zctx.socket(zmq.SUB)
            s.setsockopt(zmq.RCVHWM, BLOCK_RECV_HWM if queues[w.name].policy == "block" else DROP_RECV_HWM)
            s.setsockopt(zmq.LINGER, 0)
            s.setsockopt(zmq.MAXMSGSIZE, max_bytes)  # refuse oversized frames before allocating them
            s.connect(w.endpoint)
            s.setsockopt(zmq.SUBSCRIBE, w.topic.encode())
            self.socks[s] = w
        self.topic_bytes = {s: w.topic.encode() for s, w in self.socks.items()}
        self.pending: dict[zmq.Socket, tuple] = {}

    def run(self) -> None:
        poller = zmq.Poller()
        poller.register(self.wake, zmq.POLLIN)
        for s in self.socks:
            poller.register(s, zmq.POLLIN)
        while not self.stopping:
            for sock, _ in poller.poll(500):
                if sock is self.wake:
                    self.wake.recv()
                    self._retry_pending(poller)
                elif sock not in self.pending:
                    self._receive(sock, poller)
        for s in list(self.socks) + [self.wake]:
            s.close(0)

    def _receive(self, sock: zmq.Socket, poller: zmq.Poller) -> None:
        w = self.socks[sock]
        topic = self.topic_bytes[sock]
        while sock not in self.pending and sock.get(zmq.EVENTS) & zmq.POLLIN:
            frames = sock.recv_multipart(copy=False)
            if frames[0].bytes != topic:
                continue  # prefix match of another topic
            if wire.is_eos(frames):
                self._push(w.name, (EOS_MARK, None))
                poller.unregister(sock)
                del self.socks[sock]
                sock.close(0)  # tells the publisher this subscriber has everything
                return
            else:
                try:
                    _, env, msg = wire.decode(frames, expected=w.type_name, max_bytes=self.max_bytes)
                    item = (msg, msg.header.seq)
                except SchemaError as exc:
                    with self.cond:
                        self.queues[w.name].invalid += 1
                    log.error("input %r (topic %s): discarded invalid message: %s", w.name, w.topic, exc)
                    continue
            if not self._push(w.name, item):
                self.pending[sock] = item
                poller.unregister(sock)

    def _push(self, name: str, item: tuple) -> bool:
        with self.cond:
            q = self.queues[name]
            if item[0] is EOS_MARK:
                q.eos = True
                self.eos_seen = True
            else:
                self.arrivals += 1
                if not q.push(self.arrivals, item[0], item[1]):
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
        wake_tx.send(b"")
