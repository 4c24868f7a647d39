"""Sockets of one node process: the XPUB publisher (the receiver thread is in ``receiver.py``).

The publisher is an XPUB with NODROP, so a send waits (instead of silently dropping) when a
subscriber's pipe is full; only ``block`` inputs ever let their pipe fill, which is exactly the
backpressure that policy asks for. XPUB also reports each subscription, which is what the
readiness barrier counts. The receiver thread drains every SUB socket continuously, decodes, and
applies each input's queue policy, so a slow callback never stalls upstream for other policies.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from typing import Callable

import zmq

from probeless import wire
from probeless.errors import TransportError
from probeless.messages.base import Message

log = logging.getLogger("probeless.transport")
SEND_HWM = 16


class Publisher:
    """One node's output socket: publishes messages with per-topic seq, counts subscriptions."""

    def __init__(self, zctx: zmq.Context, endpoint: str, publisher_id: str,
                 now_ns: Callable[[], int] = time.time_ns):
        self.publisher_id = publisher_id
        self.now_ns = now_ns  # publish time: wall clock, or recorded time on replay (deterministic)
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

    def publish_raw(self, topic: str, frames: list, should_stop: Callable[[], bool]) -> None:
        """Send recorded frames ``[meta, buffers...]`` unchanged on ``topic`` (bit-exact replay)."""
        self._send([topic.encode(), *frames], should_stop)
        self.published[topic] += 1

    def publish(self, topic: str, msg: Message, should_stop: Callable[[], bool]) -> None:
        """Send ``msg`` on ``topic`` with the next seq; waits under backpressure until sent or stopped."""
        seq = self.seq[topic]
        self.seq[topic] = seq + 1
        frames = wire.encode(topic, msg, self.publisher_id, self.now_ns(), seq=seq)
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


# The receiver side lives in probeless.runtime.receiver; re-exported for existing imports.
from probeless.runtime.receiver import BLOCK_RECV_HWM, DROP_RECV_HWM, EOS_MARK, InputWire, RawMessage, Receiver  # noqa: E402,F401
