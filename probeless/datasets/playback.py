"""Pacing of a source node that plays frames from disk: recorded timing scaled by ``rate``, or lockstep.

A *group* is ``(stamp_ns, [(output, message), ...])``: everything published for one frame. Groups
are produced on a read-ahead thread (image decoding releases the GIL) and published from a 1 ms
timer on the node's thread. Group k is due at ``t0 + (stamp_k - stamp_0) / rate``; when the node
falls behind by more than ``max_lag_s`` the schedule shifts instead of bursting. ``rate == 0`` is
lockstep: before each group the player waits until the rest of the graph is idle
(``ctx.wait_quiescent()``), so every frame is processed and runs are deterministic.

Stamps: ``"dataset"`` publishes the groups' own stamps; ``"wall"`` moves every message of a group
by ``ctx.now_ns() - group stamp`` when it is published (like a live camera's host stamps; the
differences within a frame, e.g. colour to depth, are kept).

Looping: pass ``k`` of the data is produced by ``make_groups(k)``; the caller offsets its stamps so
they keep increasing across passes (synchronisers drop stamps that go backwards).
"""

from __future__ import annotations

import time
from typing import Callable, Iterator

from probeless.messages.base import Message
from probeless.messages.header import shift_stamp
from probeless.runtime.pacing import Pacer, ReadAhead

Group = tuple[int, list[tuple[str, Message]]]
READ_AHEAD_FRAMES = 8
STAMPS = ("dataset", "wall")

class Playback:
    """Publishes the groups of ``make_groups(pass)`` through ``ctx`` (see the module docstring)."""

    def __init__(self, ctx, make_groups: Callable[[int], Iterator[Group]], *, rate: float, loop: bool,
                 max_lag_s: float = 0.05, what: str = "frames", stamps: str = "dataset"):
        if stamps not in STAMPS:
            raise ValueError(f"stamps must be one of {STAMPS}, got {stamps!r}")
        self.ctx, self.make_groups, self.rate, self.loop, self.wall = ctx, make_groups, rate, loop, stamps == "wall"
        self.max_lag_s, self.what = max_lag_s, what
        self.passes = 0
        self.published = 0
        self.pending: Group | None = None
        self.pacer = Pacer(rate) if rate > 0 else None
        self.first_stamp: int | None = None
        self.ahead: ReadAhead | None = None
        self._restart()
        self.timer = ctx.create_timer(0.001, self.step, name="play")

    def _restart(self) -> None:
        if self.ahead is not None:
            self.ahead.stop()
        k = self.passes
        self.ahead = ReadAhead(lambda: self.make_groups(k), size=READ_AHEAD_FRAMES, name="frame-read-ahead")
        self.ahead.start()

    def step(self) -> None:
        """Publish every group that is due (lockstep: at most one per call)."""
        while True:
            if self.pending is None:
                self.pending = self.ahead.next()
                if self.pending is None:
                    self._at_end()
                    return
            stamp, msgs = self.pending
            if self.first_stamp is None:
                self.first_stamp = stamp
            if self.pacer is not None:
                lag = self.pacer.wait((stamp - self.first_stamp) / 1e9)
                if lag is None:
                    return
                if lag > self.max_lag_s:
                    self.pacer.shift(lag)
            else:
                self.ctx.wait_quiescent()
            offset = self.ctx.now_ns() - stamp if self.wall else 0
            for output, msg in msgs:
                self.ctx.publish(output, shift_stamp(msg, offset) if offset else msg)
            self.published += 1
            self.pending = None
            if self.rate == 0:
                return

    def _at_end(self) -> None:
        if self.loop and self.published:
            self.passes += 1
            self._restart()
            return
        self.timer.cancel()
        self.ctx.log.info("played %d %s", self.published, self.what)
        self.ctx.stop()

    def close(self) -> None:
        if self.ahead is not None:
            self.ahead.stop()


def drain(step: Callable[[], None], ctx, timeout_s: float = 60.0) -> None:
    """Call ``step`` until ``ctx`` stops (for tests and tools driving a player without a runtime)."""
    end = time.monotonic() + timeout_s
    while not ctx.stopped:
        if time.monotonic() > end:
            raise TimeoutError(f"player did not finish within {timeout_s} s")
        step()
        time.sleep(0.0005)
