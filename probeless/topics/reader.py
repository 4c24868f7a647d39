"""Subscribing without holding up the graph: :class:`TopicReader` and :func:`wait_for_start`."""

from __future__ import annotations

import os
import threading
import time
from itertools import count as _counter
from typing import IO, Any, Iterable

import zmq

from probeless.errors import ProbelessError
from probeless.messages.base import Message
from probeless.runtime.queues import InputQueue
from probeless.runtime.receiver import InputWire, Receiver
from probeless.runtime.security import NodeCurve, tool_curve
from probeless.runtime.transport import endpoint_for_policy
from probeless.topics.catalog import graph_topics
from probeless.topics.discovery import RunningGraph

_reader_ids = _counter()


class _TimedQueue(InputQueue):
    """An InputQueue that stores (receive time [ns, monotonic], message) for each message."""

    def push(self, arrival: int, msg: Any, seq: int | None = None, nbytes: int = 0) -> bool:
        return super().push(arrival, (time.monotonic_ns(), msg), seq, nbytes)


class TopicReader:
    """Subscribes to topics through the runtime Receiver; its thread keeps draining the sockets.

    ``policy`` must be a dropping one (``drop_oldest`` or ``latest``): the reader may stop reading
    for any time without ever holding up a publisher; what it misses is counted in ``dropped``.
    """

    def __init__(self, topics: Iterable[tuple[str, str]], *, policy: str = "drop_oldest", queue_size: int = 100,
                 curve: NodeCurve | None = None):
        if policy not in ("drop_oldest", "latest"):
            raise ValueError("a tool must never use the block policy: it would hold up the graph")
        # the lossy socket: a tool that stops reading loses messages, the graph never waits for it
        self.wires = [InputWire(topic, endpoint_for_policy(endpoint, policy), topic, None)
                      for topic, endpoint in dict(topics).items()]
        self.cond = threading.Condition()
        self.queues = {w.name: _TimedQueue(w.name, policy, queue_size) for w in self.wires}
        self.zctx: zmq.Context | None = None
        self.curve = curve  # the graph's CURVE keys (tool_curve) when its tcp sockets use CURVE
        self.suspended = False
        self._open()

    def _open(self) -> None:
        self.zctx = zmq.Context()
        self.receiver: Receiver | None = None
        self.wake_tx = None
        try:
            wake = f"inproc://probeless-topic-tool-{os.getpid()}-{next(_reader_ids)}"
            self.receiver = Receiver(self.zctx, self.wires, self.queues, self.cond, wake, curve=self.curve)
            self.wake_tx = self.zctx.socket(zmq.PAIR)
            self.wake_tx.setsockopt(zmq.LINGER, 0)
            self.wake_tx.connect(wake)
            self.receiver.start()
        except zmq.ZMQError as exc:
            self.close()
            raise ProbelessError(f"cannot subscribe: {exc}") from None

    def suspend(self) -> None:
        """Unsubscribe (e.g. before the process stops on Ctrl-Z); :meth:`resume` subscribes again."""
        if not self.suspended and self.zctx is not None:
            self.close()
            self.suspended = True

    def resume(self) -> None:
        """Subscribe again after :meth:`suspend`; what was published meanwhile is not counted as lost."""
        if self.suspended:
            self.suspended = False
            with self.cond:
                for q in self.queues.values():
                    q.last_seq = None
            self._open()

    def __enter__(self) -> "TopicReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def take(self, timeout: float) -> list[tuple[str, int, Message]]:
        """Everything queued now as (topic, receive ns, message), oldest first; waits up to ``timeout``
        when nothing is queued and some topic has not ended."""
        with self.cond:
            if not any(q.items for q in self.queues.values()) and not self._all_eos():
                self.cond.wait(timeout)
            items = []
            for q in self.queues.values():
                while q.items:
                    arrival, (recv_ns, msg) = q.pop_item()
                    items.append((arrival, q.name, recv_ns, msg))
        items.sort(key=lambda i: i[0])
        return [i[1:] for i in items]

    def _all_eos(self) -> bool:
        return all(q.eos for q in self.queues.values())

    @property
    def ended(self) -> bool:
        """Every topic reached end of stream and nothing is left to take."""
        with self.cond:
            return self._all_eos() and not any(q.items for q in self.queues.values())

    def eos(self, topic: str) -> bool:
        with self.cond:
            return self.queues[topic].eos

    def counters(self, topic: str) -> dict[str, int]:
        """received (by the tool), dropped (by the tool's queue), seq_gaps (lost upstream), invalid."""
        with self.cond:
            q = self.queues[topic]
            return {"received": q.received, "dropped": q.dropped, "seq_gaps": q.seq_gaps, "invalid": q.invalid}

    def close(self) -> None:
        """Unsubscribe now (linger 0). Idempotent."""
        self.suspended = False
        if self.zctx is None:
            return
        stopped = True
        if self.receiver is not None:
            if self.receiver.is_alive():
                self.receiver.stop(self.wake_tx)
                self.receiver.join(3.0)
                stopped = not self.receiver.is_alive()
            else:  # never started: close its sockets here
                for s in list(self.receiver.socks) + [self.receiver.wake]:
                    s.close(0)
        if self.wake_tx is not None:
            self.wake_tx.close(0)
        if stopped:
            self.zctx.term()
        self.zctx = None


# -- not disturbing the start -------------------------------------------------------------------
SURELY_STARTED_S = 65.0  # past the launcher's default ready timeout (60 s): the barrier is over


def wait_for_start(graph: RunningGraph, *, timeout: float | None = None, err: IO[str] | None = None) -> bool:
    """Wait until the graph has passed its readiness barrier; False when it stopped or ``timeout`` passed.

    A node's barrier counts subscriptions per topic, so a tool subscribing to a wired topic while
    the graph starts would stand in for a real subscriber that has not connected yet, and that
    subscriber would miss the first messages. Nodes publish diagnostics only once started, so the
    wait listens to diagnostics topics no node subscribes to (subscribing to those is harmless).
    """
    if (time.time_ns() - graph.started_ns) / 1e9 > SURELY_STARTED_S:
        return True
    safe = [(t.name, t.endpoint) for t in graph_topics(graph).values()
            if t.name.endswith("/diagnostics") and not t.expected]
    if not safe:
        return True  # every node is monitored: nothing harmless to listen to; accept the small race
    t0 = time.monotonic()
    noted = False
    with TopicReader(safe, policy="latest", queue_size=1, curve=tool_curve(graph.plan)) as reader:
        while True:
            if reader.take(0.1):
                return True
            waited = time.monotonic() - t0
            if reader.ended or not graph.alive or (timeout is not None and waited > timeout):
                return False
            if not noted and waited > 1.5 and err is not None:
                print("waiting for the graph to start (subscribing earlier could make its nodes miss "
                      "their first messages)", file=err, flush=True)
                noted = True

