"""``probeless topic hz``: the publishing rate of a topic over a sliding window."""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from typing import IO, Any

import numpy as np

from probeless.runtime.security import tool_curve
from probeless.topics.catalog import _import_publisher, find_topic
from probeless.topics.discovery import RunningGraph, _launcher_gone
from probeless.topics.reader import TopicReader, wait_for_start
from probeless.topics.signals import _suspend_point


class RateStats:
    """Rate of a stream over a sliding window of messages, from header stamps, seq and receive times.

    The stamp rate uses the seq span, so messages the tool itself dropped do not lower it; period
    min/max/std use only consecutive pairs (seq + 1).
    """

    def __init__(self, window: int = 100):
        self.window = max(2, window)
        self.items: deque = deque(maxlen=self.window)   # (stamp_ns, recv_ns, seq)
        self.total = 0
        self.resets = 0

    def add(self, stamp_ns: int, recv_ns: int, seq: int | None) -> None:
        if self.items:
            last_stamp, _, last_seq = self.items[-1]
            if stamp_ns < last_stamp or (seq is not None and last_seq is not None and seq <= last_seq):
                self.items.clear()  # clock jumped back or the publisher restarted
                self.resets += 1
        self.items.append((stamp_ns, recv_ns, seq))
        self.total += 1

    def report(self) -> dict[str, Any]:
        items = list(self.items)
        rep: dict[str, Any] = {"count": self.total, "window": len(items), "rate_hz": None, "receive_hz": None,
                               "min_ms": None, "max_ms": None, "mean_ms": None, "std_ms": None}
        if len(items) < 2:
            return rep
        (s0, r0, q0), (s1, r1, q1) = items[0], items[-1]
        n_periods = (q1 - q0) if q0 is not None and q1 is not None and q1 > q0 else len(items) - 1
        if s1 > s0:
            rep["rate_hz"] = n_periods / ((s1 - s0) / 1e9)
            rep["mean_ms"] = (s1 - s0) / n_periods / 1e6
        if r1 > r0:
            rep["receive_hz"] = (len(items) - 1) / ((r1 - r0) / 1e9)
        periods = np.array([(b[0] - a[0]) / 1e6 for a, b in zip(items, items[1:])
                            if a[2] is None or b[2] is None or b[2] == a[2] + 1])
        if periods.size:
            rep.update(min_ms=float(periods.min()), max_ms=float(periods.max()), std_ms=float(periods.std()))
        return rep


def _fmt(v: float | None, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def format_rate(rep: dict[str, Any]) -> str:
    return (f"rate {_fmt(rep['rate_hz'], '.3f')} Hz  period min {_fmt(rep['min_ms'], '.3f')} "
            f"max {_fmt(rep['max_ms'], '.3f')} std {_fmt(rep['std_ms'], '.3f')} ms  (stamps, window {rep['window']})"
            f"  receive {_fmt(rep['receive_hz'], '.3f')} Hz  seq gaps {rep['seq_gaps']}"
            f"  tool dropped {rep['tool_dropped']}  messages {rep['count']}")


def hz(graph: RunningGraph, topic_name: str, *, window: int = 100, duration: float | None = None,
       queue_size: int = 1000, interval: float = 1.0, out: IO[str] | None = None,
       err: IO[str] | None = None) -> dict[str, Any]:
    """Print the topic's rate once per ``interval`` until ``duration``, end of stream, the graph's end
    or Ctrl-C; return the final statistics (RateStats.report() plus seq_gaps, tool_dropped, reason)."""
    out, err = out or sys.stdout, err or sys.stderr
    topic = find_topic(graph, topic_name)
    _import_publisher(topic)
    stats = RateStats(window)
    try:
        if topic.expected and not wait_for_start(graph, err=err, timeout=duration):
            print(f"{topic.name}: the graph did not start", file=err)
            return dict(stats.report(), seq_gaps=0, tool_dropped=0, invalid=0, reason="not started")
    except KeyboardInterrupt:
        return dict(stats.report(), seq_gaps=0, tool_dropped=0, invalid=0, reason="interrupted")
    t0 = time.monotonic()
    next_print = t0 + interval
    last_total = 0
    check: dict = {}
    reason = None
    with TopicReader([(topic.name, topic.endpoint)], policy="drop_oldest", queue_size=queue_size,
                     curve=tool_curve(graph.plan)) as reader:
        def report() -> dict[str, Any]:
            c = reader.counters(topic.name)
            return dict(stats.report(), seq_gaps=c["seq_gaps"], tool_dropped=c["dropped"], invalid=c["invalid"])

        try:
            while reason is None:
                if _suspend_point(reader, err):
                    stats.items.clear()  # receive times span the pause: start the window afresh
                now = time.monotonic()
                end = t0 + duration if duration is not None else math.inf
                for _, recv_ns, msg in reader.take(max(0.0, min(next_print, end) - now)):
                    header = getattr(msg, "header", None)
                    if header is not None:
                        stats.add(header.stamp_ns, recv_ns, header.seq)
                now = time.monotonic()
                if now >= end:
                    reason = "duration"
                elif reader.ended:
                    reason = "end of stream"
                elif _launcher_gone(graph, check):
                    reason = "the graph stopped"
                if now >= next_print and reason is None:
                    next_print += interval * max(1, math.floor((now - next_print) / interval) + 1)
                    if stats.total == last_total:
                        print(f"{topic.name}: no new messages", file=out, flush=True)
                    else:
                        print(f"{topic.name}: {format_rate(report())}", file=out, flush=True)
                    last_total = stats.total
        except KeyboardInterrupt:
            reason = "interrupted"
        final = dict(report(), reason=reason)
    print(f"{topic.name} ({reason}): {format_rate(final)}", file=out, flush=True)
    return final
