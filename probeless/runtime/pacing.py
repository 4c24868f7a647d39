"""Pacing for source nodes that publish recorded time: a read-ahead thread and a real-time schedule.

A source publishes item ``i`` at ``t0 + t_i / rate`` (``t_i``: its recorded time in seconds from
any origin; ``t0`` is fixed by the first item). A node timer ticks every millisecond; an item due
within :data:`PRECISE_SLEEP_S` is waited for with ``time.sleep`` instead, so intervals are kept
to a fraction of a millisecond.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Callable, Iterator

PRECISE_SLEEP_S = 0.003  # a message due this soon is waited for with time.sleep, not the 1 ms timer
_END = object()


class ReadAhead(threading.Thread):
    """Reads items on its own thread into a bounded queue, so decoding (decompression, image
    decoding: they release the GIL) never sits between two publishes on the node's thread."""

    def __init__(self, items: Callable[[], Iterator], size: int = 64, name: str = "read-ahead"):
        super().__init__(name=name, daemon=True)
        self.items = items
        self.queue: queue.Queue = queue.Queue(maxsize=size)
        self.stopping = False
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            for item in self.items():
                while not self.stopping:
                    try:
                        self.queue.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if self.stopping:
                    return
        except BaseException as exc:  # surfaced on the node's thread
            self.error = exc
        self.queue.put(_END)

    def next(self):
        """The next item, ``None`` at the end; re-raises on this thread what the reader raised."""
        item = self.queue.get()
        if item is _END:
            if self.error is not None:
                raise self.error
            return None
        return item

    def stop(self) -> None:
        self.stopping = True


class Pacer:
    """Real-time schedule at ``rate`` × recorded speed (``rate`` > 0)."""

    def __init__(self, rate: float):
        if not rate > 0:
            raise ValueError(f"pacing rate must be > 0, got {rate}")
        self.rate = float(rate)
        self.t0: float | None = None

    def reset(self) -> None:
        """Forget the origin: the next item is due at once (a loop, a seek)."""
        self.t0 = None

    def due(self, t_s: float) -> float:
        """Monotonic time [s] at which recorded time ``t_s`` is due (after the first :meth:`wait`)."""
        return self.t0 + t_s / self.rate

    def wait(self, t_s: float) -> float | None:
        """``None`` when the item at recorded time ``t_s`` is not due yet (come back on the next
        tick); else wait precisely until it is due and return how late it is [s] (>= 0)."""
        now = time.monotonic()
        if self.t0 is None:
            self.t0 = now - t_s / self.rate
        due = self.t0 + t_s / self.rate
        if due - now > PRECISE_SLEEP_S:
            return None
        if due > now:
            time.sleep(due - now)
            return 0.0
        return now - due

    def shift(self, lag_s: float) -> None:
        """Move the schedule ``lag_s`` later: after falling behind, every stream slows down together."""
        if self.t0 is not None:
            self.t0 += lag_s
