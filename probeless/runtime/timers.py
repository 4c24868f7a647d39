"""Periodic timers run on the node's thread; late ticks are skipped and counted, never burst."""

from __future__ import annotations

import heapq
import itertools
from dataclasses import dataclass, field
from typing import Callable


@dataclass(order=True)
class Timer:
    """A periodic callback; ``fire(missed)`` is called with the number of skipped periods."""

    deadline_ns: int
    order: int
    period_ns: int = field(compare=False)
    name: str = field(compare=False)
    fire: Callable[[int], None] = field(compare=False, repr=False)
    cancelled: bool = field(default=False, compare=False)
    missed_total: int = field(default=0, compare=False)

    def cancel(self) -> None:
        self.cancelled = True


class TimerSet:
    """Timers ordered by deadline (monotonic ns)."""

    def __init__(self) -> None:
        self._heap: list[Timer] = []
        self._order = itertools.count()

    def add(self, period_ns: int, name: str, fire: Callable[[int], None], start_ns: int) -> Timer:
        if period_ns <= 0:
            raise ValueError(f"timer {name!r}: period must be positive")
        timer = Timer(start_ns + period_ns, next(self._order), period_ns, name, fire)
        heapq.heappush(self._heap, timer)
        return timer

    def next_deadline(self) -> int | None:
        while self._heap and self._heap[0].cancelled:
            heapq.heappop(self._heap)
        return self._heap[0].deadline_ns if self._heap else None

    def pop_due(self, now_ns: int) -> list[tuple[Timer, int]]:
        """Timers whose deadline passed, with the periods missed; rescheduled on the period grid."""
        due = []
        while self._heap and self._heap[0].deadline_ns <= now_ns:
            timer = heapq.heappop(self._heap)
            if timer.cancelled:
                continue
            missed = (now_ns - timer.deadline_ns) // timer.period_ns
            timer.missed_total += missed
            timer.deadline_ns += (missed + 1) * timer.period_ns
            heapq.heappush(self._heap, timer)
            due.append((timer, missed))
        return due

    def reset(self, now_ns: int) -> None:
        """Reschedule every timer one period after ``now_ns`` (time base changed or jumped)."""
        for timer in self._heap:
            timer.deadline_ns = now_ns + timer.period_ns
        heapq.heapify(self._heap)
