"""The brightness change Δ summed over time, for colours fused at different times (paper 003 §4.5).

The dense model's points were last fused at different times: a point fused before a light switch
still has the old brightness, one fused after it has the new. Each needs the Δ measured since it
was last fused: ``total() - at(stamp)``. Δ messages are added in stamp order; a late one is
inserted where it belongs.
"""

from __future__ import annotations

import bisect

import numpy as np


class DeltaHistory:
    """Cumulative Δ [camera LDR units, RGB] as a step function of the stamp [ns]."""

    def __init__(self, max_entries: int = 1_000_000):
        self.stamps: list[int] = []
        self.deltas: list[np.ndarray] = []
        self._cum: np.ndarray | None = None  # (len + 1, 3) cumulative sums, rebuilt lazily
        self.max_entries = max_entries

    def add(self, stamp_ns: int, delta) -> None:
        """Record the change ``delta`` (3,) measured at ``stamp_ns``."""
        d = np.asarray(delta, np.float64).reshape(3)
        if not np.all(np.isfinite(d)):
            raise ValueError(f"DeltaHistory.add: non-finite delta {delta!r}")
        i = bisect.bisect_right(self.stamps, int(stamp_ns))
        self.stamps.insert(i, int(stamp_ns))
        self.deltas.insert(i, d)
        if len(self.stamps) > self.max_entries:  # fold the oldest into the second: totals stay exact
            self.deltas[1] = self.deltas[1] + self.deltas[0]
            del self.stamps[0], self.deltas[0]
        self._cum = None

    def _cumulative(self) -> np.ndarray:
        if self._cum is None:
            rows = np.zeros((len(self.deltas) + 1, 3))
            if self.deltas:
                rows[1:] = np.cumsum(np.stack(self.deltas), axis=0)
            self._cum = rows
        return self._cum

    def total(self) -> np.ndarray:
        """(3,) sum of every Δ recorded."""
        return self._cumulative()[-1].copy()

    def at(self, stamps_ns) -> np.ndarray:
        """(N, 3) sum of the Δ with stamp <= each of ``stamps_ns`` (N,)."""
        s = np.asarray(stamps_ns, np.int64).reshape(-1)
        idx = np.searchsorted(np.asarray(self.stamps, np.int64), s, side="right")
        return self._cumulative()[idx]

    def since(self, stamps_ns) -> np.ndarray:
        """(N, 3) float32 sum of the Δ after each stamp: what a colour fused then still lacks."""
        return (self.total()[None, :] - self.at(stamps_ns)).astype(np.float32)
