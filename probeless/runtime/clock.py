"""Node time: the wall clock live, or the recorded time of a replay's clock topic.

On replay the player publishes ``core/Clock``; every node follows it, so ``ctx.now_ns()`` and
node timers run in recorded time (scaled by the playback rate), and a replay loop (the clock's
``epoch`` changes) resets timers and calls the node's ``on_time_reset`` hook.
"""

from __future__ import annotations

import time

from probeless.messages.header import Clock


class NodeClock:
    """Wall time until the first Clock message arrives, simulated time after."""

    def __init__(self) -> None:
        self.sim_ns: int | None = None
        self.epoch = 0
        self.rate = 1.0

    @property
    def simulated(self) -> bool:
        return self.sim_ns is not None

    def now_ns(self) -> int:
        """Wall clock [ns since epoch], or the latest recorded time on replay."""
        return self.sim_ns if self.sim_ns is not None else time.time_ns()

    def monotonic_ns(self) -> int:
        """Time base of timers: monotonic wall time, or the recorded time on replay."""
        return self.sim_ns if self.sim_ns is not None else time.monotonic_ns()

    def update(self, msg: Clock) -> bool:
        """Take a clock message; True when timers must be rescheduled (first clock, or a jump back)."""
        first = self.sim_ns is None
        jumped = msg.epoch != self.epoch or (self.sim_ns is not None and msg.header.stamp_ns < self.sim_ns)
        self.sim_ns, self.epoch, self.rate = msg.header.stamp_ns, msg.epoch, msg.rate
        return first or jumped
