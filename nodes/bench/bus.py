"""Nodes of the bus benchmark (``probeless bench bus``): an image source and a measuring sink, registered
as ``bench_source`` and ``bench_sink``.

``BenchSource`` publishes ``Image`` messages in two phases: a back-to-back burst (throughput,
``header.frame_id = "tput"``) and then a paced stream (latency, ``frame_id = "lat"``). Each message
is stamped with ``time.time_ns()`` just before it is published. ``BenchSink`` records, per phase,
receive time minus stamp, the seqs and the first/last receive times, and writes them as JSON to
``out_path`` in ``close()``.

Profiling hook: with ``PROBELESS_BENCH_PROFILE=DIR`` set, each bench node runs its own thread (and
the sink its receiver thread) under cProfile and dumps ``DIR/<node_id>.<thread>.prof``.
Tracing hook: with ``PROBELESS_BENCH_TRACE=1`` the sink also records, per message, the envelope's
publish time and the receiver thread's decode start/end (``trace`` in its JSON: seq -> [publish_ns,
decode_start_ns, decode_end_ns]), to split the latency into send, receive and hand-off.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass

from probeless.datasets.synthetic_frames import bench_image
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.runtime import Node, param

PROFILE_ENV = "PROBELESS_BENCH_PROFILE"
TRACE_ENV = "PROBELESS_BENCH_TRACE"
PHASE_TPUT = "tput"
PHASE_LAT = "lat"


def _profiler(node_id: str, thread: str):
    """(profile, dump) when the profiling hook is on, else (None, no-op)."""
    out = os.environ.get(PROFILE_ENV)
    if not out:
        return None, lambda: None
    import cProfile

    prof = cProfile.Profile()

    def dump() -> None:
        os.makedirs(out, exist_ok=True)
        prof.dump_stats(os.path.join(out, f"{node_id}.{thread}.prof"))

    return prof, dump


class BenchSource(Node):
    """Publishes ``count`` images back to back, waits ``gap_s``, then ``paced_count`` at ``rate_hz``; stops."""

    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        width: int = param(640, min=1, max=16384, doc="image width [px]")
        height: int = param(480, min=1, max=16384, doc="image height [px]")
        count: int = param(100, min=0, doc="messages of the back-to-back (throughput) phase")
        paced_count: int = param(0, min=0, doc="messages of the paced (latency) phase")
        rate_hz: float = param(100.0, min=0.1, max=100000.0, doc="rate of the paced phase [Hz]")
        burst: int = param(64, min=1, doc="messages published per timer tick in the throughput phase")
        gap_s: float = param(0.2, min=0.0, doc="pause between the phases, lets queues drain [s]")

    def setup(self) -> None:
        p = self.params
        self.data = bench_image(p.width, p.height)
        self.sent = 0
        self.paced_sent = 0
        self.paced_start: int | None = None
        self.prof, self.dump = _profiler(self.ctx.node_id, "main")
        self.timer = self.ctx.create_timer(1e-6, self._burst, name="bench_burst")
        if p.count == 0:
            self._to_paced()

    def _publish(self, phase: str) -> None:
        stamp = time.time_ns()
        self.ctx.publish("image", Image(Header(stamp, phase), self.data, "rgb8"))

    def _burst(self) -> None:
        if self.prof is not None:
            self.prof.enable()
        try:
            n = min(self.params.burst, self.params.count - self.sent)
            for _ in range(n):
                self._publish(PHASE_TPUT)
            self.sent += n
        finally:
            if self.prof is not None:
                self.prof.disable()
        if self.sent >= self.params.count:
            self._to_paced()

    def _to_paced(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
        if self.params.paced_count == 0:
            self.ctx.stop()
            return
        self.paced_start = time.monotonic_ns() + int(self.params.gap_s * 1e9)
        self.timer = self.ctx.create_timer(1.0 / self.params.rate_hz, self._paced, name="bench_paced")

    def _paced(self) -> None:
        if time.monotonic_ns() < self.paced_start:
            return
        if self.prof is not None:
            self.prof.enable()
        try:
            self._publish(PHASE_LAT)
        finally:
            if self.prof is not None:
                self.prof.disable()
        self.paced_sent += 1
        if self.paced_sent >= self.params.paced_count:
            self.timer.cancel()
            self.ctx.stop()

    def close(self) -> None:
        self.dump()


class _Phase:
    __slots__ = ("recv_ns", "stamp_ns", "seqs")

    def __init__(self) -> None:
        self.recv_ns: list[int] = []
        self.stamp_ns: list[int] = []
        self.seqs: list[int] = []


class BenchSink(Node):
    """Records receive times, stamps and seqs per phase; writes them to ``out_path`` on close."""

    INPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        out_path: str = param(doc="JSON file the measurements are written to")

    def setup(self) -> None:
        self.phases = {PHASE_TPUT: _Phase(), PHASE_LAT: _Phase()}
        self.other = 0
        self.bad_shape = 0
        self.shape: tuple | None = None
        self.prof, self.dump = _profiler(self.ctx.node_id, "main")
        self.trace: dict[int, list[int]] = {}
        if os.environ.get(TRACE_ENV):
            self._trace_decode()
        if self.prof is not None:
            self._profile_receiver()
            self.prof.enable()

    def _trace_decode(self) -> None:
        """Wrap wire.decode (as the receiver thread calls it) to timestamp each message."""
        from probeless import wire

        original = wire.decode
        trace = self.trace

        def decode(frames, **kw):
            t0 = time.time_ns()
            out = original(frames, **kw)
            trace[out[2].header.seq] = [out[1].publish_ns, t0, time.time_ns()]
            return out

        wire.decode = decode

    def _profile_receiver(self) -> None:
        """Run the (not yet started) receiver thread of this process under its own profiler."""
        from probeless.runtime import transport

        rprof, dump_receiver = _profiler(self.ctx.node_id, "receiver")
        original = transport.Receiver.run

        def run(receiver) -> None:
            rprof.enable()
            try:
                original(receiver)
            finally:
                rprof.disable()
                dump_receiver()

        transport.Receiver.run = run

    def on_input(self, name: str, msg: Image) -> None:
        now = time.time_ns()
        phase = self.phases.get(msg.header.frame_id)
        if phase is None:
            self.other += 1
            return
        phase.recv_ns.append(now)
        phase.stamp_ns.append(msg.header.stamp_ns)
        phase.seqs.append(msg.header.seq)
        if self.shape is None:
            self.shape = msg.data.shape
        elif msg.data.shape != self.shape:
            self.bad_shape += 1

    def close(self) -> None:
        if self.prof is not None:
            self.prof.disable()
            self.dump()
        out = {"other": self.other, "bad_shape": self.bad_shape,
               "shape": list(self.shape) if self.shape else None, "trace": self.trace,
               "phases": {k: {"recv_ns": p.recv_ns, "stamp_ns": p.stamp_ns, "seqs": p.seqs}
                          for k, p in self.phases.items()}}
        tmp = self.params.out_path + ".tmp"
        with open(tmp, "w") as f:
            json.dump(out, f)
        os.replace(tmp, self.params.out_path)
