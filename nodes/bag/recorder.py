"""Bag recorder node: writes every message it receives, exactly as it crossed the wire, to MCAP.

Inputs are raw (nothing decoded but the envelope), any name, any type; the launcher wires one
``policy: block`` input per recorded topic, so the recorder never drops: if it cannot keep up,
its publishers wait. Losses upstream still show as seq gaps; they are printed and stored in the
file as an INCOMPLETE report (metadata ``probeless.incomplete``).

When a write fails (disk full, I/O error) the recorder logs one error naming the file, stops recording (the file
keeps its complete chunks and is sealed where space allows, see :class:`BagWriter`) and goes on taking its inputs
without storing them, so the rest of the graph keeps running; at the end it reports how many messages were not
recorded and the node exits with an error. The file's metadata never holds environment variables or secrets
(:func:`probeless.provenance.recording_metadata`).
"""

from __future__ import annotations

from dataclasses import dataclass

from probeless import __version__
from probeless.bag.writer import INCOMPLETE, BagWriter
from probeless.errors import BagError
from probeless.provenance import recording_metadata
from probeless.runtime import Node, param
from probeless.runtime.params import writable_file_problem
from probeless.runtime.receiver import RawMessage


class SeqTracker:
    """Counts messages missing per topic from header.seq gaps (a smaller seq = publisher restart)."""

    def __init__(self) -> None:
        self.last: dict[str, int] = {}
        self.missing: dict[str, int] = {}

    def add(self, topic: str, seq: int) -> None:
        last = self.last.get(topic)
        if last is not None and seq > last + 1:
            self.missing[topic] = self.missing.get(topic, 0) + seq - last - 1
        self.last[topic] = seq

    def report(self) -> dict[str, str]:
        return {t: f"INCOMPLETE: {n} message(s) missing (seq gaps)" for t, n in sorted(self.missing.items())}


class BagRecorder(Node):
    """Records its raw inputs into an MCAP file (one channel per topic)."""

    INPUTS = {"*": None}
    RAW_INPUTS = True

    @dataclass(frozen=True)
    class Params:
        path: str = param(check=writable_file_problem, doc="output .mcap file")
        compression: str = param("lz4", choices=("lz4", "zstd", "none"), doc="chunk compression")
        max_size_mb: float = param(0.0, min=0.0, doc="split into _000, _001, ... files of this size; 0 = no split")
        max_duration_s: float = param(0.0, min=0.0, doc="split after this much recorded time; 0 = no split")
        force: bool = param(False, doc="overwrite an existing file")
        direct_io: bool = param(True, doc="write without the page cache (O_DIRECT) where the file system allows")
        command: str = param("", doc="command line that started the recording (stored in the file)")

    def setup(self) -> None:
        p = self.params
        plan = getattr(self.ctx, "plan", {}) or {}
        meta = recording_metadata(plan, p.command, __version__)  # secrets redacted, no environment
        self.writer = BagWriter(p.path, compression=p.compression, force=p.force, direct_io=p.direct_io,
                                max_size=int(p.max_size_mb * 1e6) or None, max_duration_s=p.max_duration_s or None,
                                metadata={"probeless.graph": meta})
        self.seqs = SeqTracker()
        self.count = 0
        self.lost = 0   # messages not recorded after a failed write
        self.step: list[tuple[int, str, int, RawMessage]] = []

    def on_input(self, name: str, msg: RawMessage) -> None:
        self.seqs.add(msg.topic, msg.seq)
        if not self.ctx.simulated_time:
            self._write(msg, msg.recv_ns)
            return
        # Replay: log time is the recorded clock. Messages of one clock step are written sorted by
        # (topic, seq), so a lockstep replay gives the same file whatever the arrival order.
        now = self.ctx.now_ns()
        if self.step and self.step[0][0] != now:
            self._flush_step()
        self.step.append((now, msg.topic, msg.seq, msg))

    def _flush_step(self) -> None:
        for log_ns, _, _, msg in sorted(self.step, key=lambda s: (s[1], s[2])):
            self._write(msg, log_ns)
        self.step = []

    def _write(self, msg: RawMessage, log_ns: int) -> None:
        if self.writer.failed:
            self.lost += 1  # recording stopped (disk full, I/O error): keep draining so the graph runs on
            return
        try:
            # the zmq frames are copied once, straight into the chunk in progress; then they can go
            self.writer.write(msg.topic, msg.type_name, msg.version, msg.frames, log_time_ns=log_ns,
                              publish_time_ns=msg.publish_ns, sequence=msg.seq)
        except BagError:
            if not self.writer.failed:
                raise  # not a failed write (an unknown type, a changed topic type): the recorder's own error
            self.lost += 1
            self.ctx.log.error("%s; the graph keeps running, later messages are not recorded", self.writer.failed)
            return
        self.count += 1

    def close(self) -> None:
        if not hasattr(self, "writer"):
            return  # setup failed before the file was open: nothing to flush
        self._flush_step()
        report = self.seqs.report()
        for topic, text in report.items():
            self.ctx.log.warning("%s: %s", topic, text)
        if self.writer.failed:
            raise BagError(f"{self.writer.failed}; {self.lost} message(s) after the failure were not recorded")
        self.writer.close(extra_metadata={INCOMPLETE: report} if report else None)
        self.ctx.log.info("recorded %d message(s) to %s", self.count, ", ".join(map(str, self.writer.paths)))
