"""Sockets of one node process: the publisher (the receiver thread is in ``receiver.py``).

Every node publishes each output on two XPUB sockets, and each subscriber connects to the one its
queue policy asks for, so backpressure is per subscriber:

* **lossless** (``endpoint``, XPUB_NODROP) for ``block`` inputs: a send waits while such a
  subscriber's pipe is full. That is the backpressure the policy asks for, and the only way a
  subscriber can ever slow a publisher.
* **lossy** (:func:`lossy_endpoint`) for ``latest`` and ``drop_oldest`` inputs and for the topic
  tools: libzmq drops a message for a peer whose pipe is full, for that peer alone, and the send
  never waits. The subscriber sees the loss as a ``seq`` gap, counted in its diagnostics
  (``seq_gaps``) and shown by ``probeless topic info``. End-of-stream markers are the exception:
  they are sent losslessly on both sockets.

XPUB also reports each subscription, which is what the readiness barrier counts, and what a latched
output answers: it sends its last message again to the late joiner (``latching.py``). A pipe holds at
most ``SEND_HWM`` messages at the publisher plus the subscriber's receive HWM (``receiver.py``),
so a stopped subscriber costs bounded memory.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from typing import Any, Callable, Iterable

import zmq

from probeless import wire
from probeless.errors import TransportError
from probeless.messages.base import Message
from probeless.runtime.latching import LATCH_MARK
from probeless.runtime.security import NodeCurve

log = logging.getLogger("probeless.transport")
SEND_HWM = 16
LOSSLESS_POLICIES = ("block",)


def lossy_endpoint(endpoint: str) -> str:
    """The lossy twin of a node's (lossless) publisher endpoint: ``X.pub`` -> ``X.lossy``, tcp PORT -> PORT+1."""
    if endpoint.startswith("tcp://"):
        addr, _, port = endpoint.rpartition(":")
        return f"{addr}:{int(port) + 1}"
    return endpoint[:-4] + ".lossy" if endpoint.endswith(".pub") else endpoint + ".lossy"


def endpoint_for_policy(endpoint: str, policy: str) -> str:
    """Where a subscriber with queue ``policy`` connects, given the publisher's (lossless) ``endpoint``."""
    return endpoint if policy in LOSSLESS_POLICIES else lossy_endpoint(endpoint)


class _Socket:
    """One XPUB of a publisher with the subscriptions it has seen."""

    def __init__(self, zctx: zmq.Context, endpoint: str, publisher_id: str, lossless: bool,
                 curve: NodeCurve | None = None):
        self.endpoint, self.lossless = endpoint, lossless
        self.sock = zctx.socket(zmq.XPUB)
        self.sock.setsockopt(zmq.XPUB_NODROP, 1 if lossless else 0)
        self.sock.setsockopt(zmq.XPUB_VERBOSER, 1)   # every subscribe and unsubscribe, even duplicates
        self.sock.setsockopt(zmq.SNDHWM, SEND_HWM)
        self.sock.setsockopt(zmq.SNDTIMEO, 100)
        self.sock.setsockopt(zmq.LINGER, 2000)
        if "[" in endpoint:
            self.sock.setsockopt(zmq.IPV6, 1)  # tcp://[::1]:PORT
        if curve is not None:
            curve.server(zctx, self.sock, endpoint)  # CURVE server on tcp (security.py)
        try:
            self.sock.bind(endpoint)
        except zmq.ZMQError as exc:
            self.sock.close(0)  # an open socket would keep the context's term() waiting forever
            raise TransportError(f"{publisher_id}: cannot bind {endpoint}: {exc}") from None
        self.subscriptions: Counter[str] = Counter()
        self._wanted: dict[str, bool] = {}
        self.joined: set[str] = set()   # prefixes subscribed since the publisher last answered them (latched topics)

    def poll(self, timeout_ms: int) -> bool:
        """Read pending (un)subscribe notifications; True if any arrived."""
        changed = False
        while self.sock.poll(timeout_ms, zmq.POLLIN):
            event = self.sock.recv()
            if event:
                prefix = event[1:].decode(errors="replace")
                self.subscriptions[prefix] += 1 if event[0] == 1 else -1
                if event[0] == 1:
                    self.joined.add(prefix)
                changed = True
            timeout_ms = 0
        if changed:
            self._wanted.clear()
        return changed

    def wanted(self, topic: str) -> bool:
        """Whether any subscription matches ``topic`` (ZeroMQ's prefix match)."""
        hit = self._wanted.get(topic)
        if hit is None:
            hit = self._wanted[topic] = any(n > 0 and topic.startswith(s) for s, n in self.subscriptions.items())
        return hit


class Publisher:
    """One node's outputs: a lossless and a lossy XPUB, per-topic seq, subscription counts."""

    def __init__(self, zctx: zmq.Context, endpoint: str, publisher_id: str,
                 now_ns: Callable[[], int] = time.time_ns, curve: NodeCurve | None = None,
                 latched: Iterable[str] = ()):
        self.publisher_id = publisher_id
        self.now_ns = now_ns  # publish time: wall clock, or recorded time on replay (deterministic)
        self.lossy = _Socket(zctx, lossy_endpoint(endpoint), publisher_id, lossless=False, curve=curve)
        try:
            self.lossless = _Socket(zctx, endpoint, publisher_id, lossless=True, curve=curve)
        except Exception:  # a bind or key error: leave no socket behind
            self.lossy.sock.close(0)
            raise
        self.socks = (self.lossy, self.lossless)  # lossy first: a waiting lossless send never delays them
        self.seq: Counter[str] = Counter()
        self.published: Counter[str] = Counter()
        self.latched = set(latched)           # topics whose last message goes to late joiners (latching.py)
        self.last: dict[str, list[bytes]] = {}  # latched topic -> its last message's frames after the topic
        self.resent: Counter[str] = Counter()   # latched messages sent again for late joiners, per topic
        self.ended = False                      # end of stream sent: nothing is re-sent any more

    @property
    def sock(self) -> zmq.Socket:
        """The lossless socket (the one ``block`` subscribers connect to)."""
        return self.lossless.sock

    @property
    def subscriptions(self) -> Counter[str]:
        """Live subscriptions by prefix, over both sockets."""
        return self.lossless.subscriptions + self.lossy.subscriptions

    def poll_subscriptions(self, timeout_ms: int = 0) -> None:
        """Read pending (un)subscribe notifications of both sockets (waiting up to ``timeout_ms`` in all)."""
        if timeout_ms and not zmq.select([s.sock for s in self.socks], [], [], timeout_ms / 1000)[0]:
            return
        for s in self.socks:
            s.poll(0)

    def publish_raw(self, topic: str, frames: list, should_stop: Callable[[], bool]) -> None:
        """Send recorded frames ``[meta, buffers...]`` unchanged on ``topic`` (bit-exact replay)."""
        self._send(topic, [topic.encode(), *frames], should_stop)
        self.published[topic] += 1
        if topic in self.latched:
            self.last[topic] = [_owned(f) for f in frames]

    def publish(self, topic: str, msg: Message, should_stop: Callable[[], bool]) -> None:
        """Send ``msg`` on ``topic`` with the next seq; waits only for ``block`` subscribers, until sent or stopped."""
        seq = self.seq[topic]
        self.seq[topic] = seq + 1
        frames = wire.encode(topic, msg, self.publisher_id, self.now_ns(), seq=seq)
        self._send(topic, frames, should_stop)
        self.published[topic] += 1
        if topic in self.latched:
            self.last[topic] = [_owned(f) for f in frames[1:]]  # a copy: the node may reuse its arrays

    def send_eos(self, topic: str, should_stop: Callable[[], bool]) -> None:
        """End of stream on ``topic``: lossless for every subscriber, lossy ones included."""
        self.ended = True
        self.lossy.sock.setsockopt(zmq.XPUB_NODROP, 1)
        try:
            self._send(topic, [topic.encode(), wire.EOS], should_stop, every=True)
        finally:
            self.lossy.sock.setsockopt(zmq.XPUB_NODROP, 0)

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
            subs = self.subscriptions
            busy = [t for t in topics if subs[t] > 0]
            if not busy:
                return True
            if time.monotonic() - last_note > 5:
                last_note = time.monotonic()
                note(", ".join(f"{t} ({subs[t]})" for t in busy))
        return False

    def serve_late_joiners(self, should_stop: Callable[[], bool]) -> None:
        """Read new subscriptions and send each latched topic's last message to those that joined since."""
        for s in self.socks:
            if s.sock.get(zmq.EVENTS) & zmq.POLLIN:
                s.poll(0)
            self._answer_joined(s, should_stop)

    def _answer_joined(self, s: _Socket, should_stop: Callable[[], bool]) -> None:
        """The last message of every latched topic a prefix in ``s.joined`` matches, marked as a re-send."""
        if not s.joined:
            return
        joined, s.joined = s.joined, set()
        if self.ended:
            return
        for topic, frames in self.last.items():
            if any(topic.startswith(p) for p in joined):
                _send_frames(s.sock, [topic.encode() + LATCH_MARK, *frames], should_stop)
                self.resent[topic] += 1

    def _send(self, topic: str, frames: list, should_stop: Callable[[], bool], every: bool = False) -> None:
        for s in self.socks:
            if s.sock.get(zmq.EVENTS) & zmq.POLLIN:
                s.poll(0)
            if s.joined:  # on both sockets before the new message: a joiner has the latched ones first
                self._answer_joined(s, should_stop)
        for s in self.socks:
            if every or s.wanted(topic):
                _send_frames(s.sock, frames, should_stop)

    def close(self) -> None:
        for s in self.socks:
            s.sock.close()


def _owned(frame: Any) -> bytes:
    """The bytes of a frame, copied out of buffers the sender may reuse (arrays, memoryviews, zmq frames)."""
    if isinstance(frame, bytes):
        return frame
    if isinstance(frame, zmq.Frame):
        return frame.bytes
    return memoryview(frame).tobytes()


def _send_frames(sock: zmq.Socket, frames: list, should_stop: Callable[[], bool]) -> None:
    """Send one multipart message; on a NODROP socket, retry while the pipe is full until sent or stopped."""
    last = len(frames) - 1
    first = True
    for i, frame in enumerate(frames):
        flags = zmq.SNDMORE if i < last else 0
        big = getattr(frame, "nbytes", len(frame)) >= wire.ZERO_COPY_BYTES
        while True:
            try:
                sock.send(frame, flags, copy=not big)
                break
            except zmq.Again:
                # only the first frame waits: HWM counts whole messages
                if not first or should_stop():
                    raise TransportError("publish interrupted by shutdown") from None
        first = False


# The receiver side lives in probeless.runtime.receiver; re-exported for existing imports.
from probeless.runtime.receiver import BLOCK_RECV_HWM, DROP_RECV_HWM, EOS_MARK, InputWire, RawMessage, Receiver  # noqa: E402,F401
