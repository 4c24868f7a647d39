"""Is this process's memory growing without bound? A robust trend test on RSS samples.

A node's resident set grows while it warms up (imports, models, first buffers) and then should
stay flat. :class:`MemoryWatch` takes one RSS sample per diagnostics period, ignores a warm-up,
and keeps the *minimum* of each window (a minimum is immune to transient spikes: a big frame
being decoded, a GC cycle not yet run). Memory is reported growing when the window minimum has
risen in each of the last ``windows`` windows and in all by more than ``min_growth_bytes`` and
``min_growth_frac`` of the first of them: a leak rises steadily, a plateau does not.
"""

from __future__ import annotations

import os
from collections import deque
from dataclasses import dataclass, field

_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def rss_bytes() -> int:
    """Resident set size of this process [bytes] (Linux ``/proc/self/statm``; 0 where unavailable)."""
    try:
        with open("/proc/self/statm", "rb") as f:
            return int(f.read().split()[1]) * _PAGE
    except (OSError, IndexError, ValueError):
        return 0


@dataclass
class MemoryWatch:
    """Feed :meth:`sample` once per period; :attr:`growing` says whether RSS rises without bound."""

    warmup_samples: int = 60          # samples ignored at start (60 = one minute at 1 Hz)
    window: int = 30                  # samples per window
    windows: int = 6                  # consecutive rising windows that make a trend
    min_growth_bytes: int = 32 << 20
    min_growth_frac: float = 0.10
    seen: int = 0
    current: list[int] = field(default_factory=list)
    minima: deque = field(default_factory=deque)

    def __post_init__(self) -> None:
        self.minima = deque(maxlen=self.windows + 1)

    def sample(self, rss: int) -> None:
        """Add one RSS sample [bytes]."""
        self.seen += 1
        if self.seen <= self.warmup_samples or rss <= 0:
            return
        self.current.append(rss)
        if len(self.current) >= self.window:
            self.minima.append(min(self.current))
            self.current = []

    @property
    def growing(self) -> bool:
        m = list(self.minima)
        if len(m) <= self.windows:
            return False
        rising = all(b > a for a, b in zip(m, m[1:]))
        growth = m[-1] - m[0]
        return rising and growth > self.min_growth_bytes and growth > self.min_growth_frac * m[0]

    def describe(self) -> str:
        """One line for a warning: the rise over the watched windows."""
        m = list(self.minima)
        if len(m) < 2:
            return "no trend yet"
        return (f"RSS rising without bound: {m[0] / 2**20:.0f} -> {m[-1] / 2**20:.0f} MiB over the last "
                f"{len(m) - 1} windows of {self.window} samples")
