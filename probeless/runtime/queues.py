"""Per-input queue policies, implemented in the subscriber (not by ZeroMQ HWM or CONFLATE).

``latest`` keeps only the newest message, ``drop_oldest`` keeps the newest ``queue_size``, and
``block`` refuses new messages when full, so the receiver stops reading that socket and the
publisher (an XPUB with NODROP) waits: backpressure, nothing lost. Every drop is counted.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

POLICIES = ("latest", "drop_oldest", "block")


@dataclass
class InputQueue:
    """Bounded FIFO of (arrival, message) for one input, with loss counters. Not thread-safe by itself."""

    name: str
    policy: str = "drop_oldest"
    queue_size: int = 10
    items: deque = field(default_factory=deque)
    received: int = 0
    dropped: int = 0
    seq_gaps: int = 0
    invalid: int = 0
    eos: bool = False           # end of stream received: nothing more will arrive
    last_seq: int | None = None

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ValueError(f"input {self.name!r}: unknown policy {self.policy!r}, expected one of {POLICIES}")
        if self.queue_size < 1:
            raise ValueError(f"input {self.name!r}: queue_size must be >= 1")
        if self.policy == "latest":
            self.queue_size = 1

    @property
    def full(self) -> bool:
        return len(self.items) >= self.queue_size

    def push(self, arrival: int, msg: Any, seq: int | None = None) -> bool:
        """Queue a message; return False (and keep nothing) when ``block`` and full."""
        if self.policy == "block" and self.full:
            return False
        self.received += 1
        self._track_seq(seq)
        if self.full:
            self.items.popleft()
            self.dropped += 1
        self.items.append((arrival, msg))
        return True

    def _track_seq(self, seq: int | None) -> None:
        if seq is None:
            return
        if self.last_seq is not None and seq > self.last_seq + 1:
            self.seq_gaps += seq - self.last_seq - 1
        self.last_seq = seq  # a smaller seq means the publisher restarted: start counting afresh

    def head_arrival(self) -> int | None:
        return self.items[0][0] if self.items else None

    def pop(self) -> Any:
        return self.items.popleft()[1]
