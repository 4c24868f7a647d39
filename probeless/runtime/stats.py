"""Rolling timing statistics for callbacks and stages, reported in diagnostics."""

from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np

from probeless.messages.diagnostics import StageTiming


class TimingWindow:
    """Durations of one named callback since the last report, plus a running total count."""

    def __init__(self, name: str):
        self.name = name
        self.samples: list[float] = []
        self.total = 0

    def add(self, seconds: float) -> None:
        self.samples.append(seconds * 1e3)
        self.total += 1

    def report(self) -> StageTiming:
        """Summarise and reset the window."""
        s = np.asarray(self.samples, dtype=np.float64)
        self.samples = []
        if s.size == 0:
            return StageTiming(self.name, 0, self.total, 0.0, 0.0, 0.0, 0.0)
        p50, p99 = np.percentile(s, [50, 99])
        return StageTiming(self.name, int(s.size), self.total, float(s.mean()), float(p50), float(p99),
                           float(s.max()))


class Timings:
    """A set of named timing windows."""

    def __init__(self) -> None:
        self.windows: dict[str, TimingWindow] = {}

    def add(self, name: str, seconds: float) -> None:
        window = self.windows.get(name)
        if window is None:
            window = self.windows[name] = TimingWindow(name)
        window.add(seconds)

    @contextmanager
    def time(self, name: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - t0)

    def report(self) -> tuple[StageTiming, ...]:
        return tuple(w.report() for w in self.windows.values())
