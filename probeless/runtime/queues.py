"""Per-input queue policies, implemented in the subscriber (not by ZeroMQ HWM or CONFLATE).

``latest`` keeps only the newest message, ``drop_oldest`` keeps the newest ``queue_size``, and
``block`` refuses new messages when full, so the receiver stops reading that socket and the
publisher (whose lossless socket waits) waits: backpressure, nothing lost. Every queue is bounded
in bytes too (``max_bytes``): a dropping queue drops its oldest messages to make room, a ``block``
queue counts as full. Every drop is counted.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

POLICIES = ("latest", "drop_oldest", "block")
QUEUE_MAX_BYTES = 256 << 20  # per input; a single larger message is still taken when the queue is empty
RECORDER_QUEUE_BYTES = 256 << 20  # a recorder's block input queues together hold at most this [bytes]


def input_queue_bytes(n_inputs: int, total: int = RECORDER_QUEUE_BYTES) -> int:
    """The byte bound of each of a recorder's ``n_inputs`` input queues (plan key ``max_bytes``), so that together
    they hold at most ``total``. A full queue refuses messages (``policy: block``: the publisher waits); an empty
    one still takes a single larger message. The writer's own memory is bounded too: 3 chunk buffers of
    ``chunk_size`` plus one message, and one staging buffer of a chunk."""
    return max(1 << 20, total // max(1, n_inputs))


@dataclass
class InputQueue:
    """Bounded FIFO of (arrival, message) for one input, with loss counters. Not thread-safe by itself."""

    name: str
    policy: str = "drop_oldest"
    queue_size: int = 10
    max_bytes: int = QUEUE_MAX_BYTES
    items: deque = field(default_factory=deque)
    sizes: deque = field(default_factory=deque)
    queued_bytes: int = 0       # payload bytes waiting now [bytes]
    peak_bytes: int = 0         # most payload bytes ever waiting [bytes]
    received: int = 0
    dropped: int = 0
    seq_gaps: int = 0
    restarts: int = 0           # times the publisher's seq went back (it restarted) [count]
    invalid: int = 0
    eos: bool = False           # end of stream received: nothing more will arrive
    last_seq: int | None = None

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ValueError(f"input {self.name!r}: unknown policy {self.policy!r}, expected one of {POLICIES}")
        if self.queue_size < 1:
            raise ValueError(f"input {self.name!r}: queue_size must be >= 1")
        if self.max_bytes < 1:
            raise ValueError(f"input {self.name!r}: max_bytes must be >= 1")
        if self.policy == "latest":
            self.queue_size = 1

    @property
    def full(self) -> bool:
        return len(self.items) >= self.queue_size or (bool(self.items) and self.queued_bytes >= self.max_bytes)

    def push(self, arrival: int, msg: Any, seq: int | None = None, nbytes: int = 0) -> bool:
        """Queue a message of ``nbytes``; return False (and keep nothing) when ``block`` and it does not fit."""
        if self.policy == "block" and not self._fits(nbytes):
            return False
        self.received += 1
        self._track_seq(seq)
        while self.items and not self._fits(nbytes):
            self.pop_item()
            self.dropped += 1
        self.items.append((arrival, msg))
        self.sizes.append(nbytes)
        self.queued_bytes += nbytes
        self.peak_bytes = max(self.peak_bytes, self.queued_bytes)
        return True

    def _fits(self, nbytes: int) -> bool:
        if not self.items:
            return True
        return len(self.items) < self.queue_size and self.queued_bytes + nbytes <= self.max_bytes

    def _track_seq(self, seq: int | None) -> None:
        if seq is None:
            return
        if self.last_seq is not None:
            if seq > self.last_seq + 1:
                self.seq_gaps += seq - self.last_seq - 1
            elif seq <= self.last_seq:
                self.restarts += 1  # the publisher restarted: its seq starts afresh
        self.last_seq = seq

    def head_arrival(self) -> int | None:
        return self.items[0][0] if self.items else None

    def pop_item(self) -> tuple[int, Any]:
        """Remove and return the oldest ``(arrival, message)``."""
        self.queued_bytes -= self.sizes.popleft()
        return self.items.popleft()

    def pop(self) -> Any:
        return self.pop_item()[1]
