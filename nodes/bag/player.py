"""Bag player node: publishes a recording's messages bit-exact, in log-time order, with its timing.

Timing: message i is due at ``t0 + (log_time_i - log_time_0) / rate``. When the machine falls
behind by more than ``max_lag_s`` the schedule shifts (all topics slow down together; nothing is
reordered or skipped). ``lockstep`` publishes the next message only when every other node has
finished with the previous one (the launcher's quiescence check), so outputs are deterministic;
``rate: 0`` means lockstep as fast as possible. A ``core/Clock`` on output ``clock`` carries the
recorded time to every node of the graph; its ``epoch`` grows at each loop.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

from probeless.bag.reader import BagMessage, BagReader
from probeless.bag.schema import check_schemas
from probeless.errors import BagError, ParamError
from probeless.launch.replay import parse_remaps
from probeless.messages.header import Clock, Header
from probeless.runtime import Node, param
from probeless.runtime.pacing import Pacer, ReadAhead

CLOCK_PERIOD_NS = 10_000_000
READ_AHEAD = 64  # messages decoded ahead of playback
GIL_SWITCH_S = 0.0002  # GIL hand-over interval in the player process [s]


def _remap_problem(remap: tuple[str, ...]) -> str | None:
    """The remap param's rule (a param check): every item is from:=to."""
    try:
        parse_remaps(remap)
    except ValueError as exc:
        return str(exc)
    return None


class BagPlayer(Node):
    """Publishes the messages of an MCAP recording on their (remapped) topics."""

    OUTPUTS = {"*": None, "clock": Clock}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="file", must_exist=True, doc="recording to play (.mcap)")
        rate: float = param(1.0, min=0.0, max=1000.0, doc="speed factor; 0 = as fast as possible without loss")
        loop: bool = param(False, doc="start again at the end")
        lockstep: bool = param(False, doc="publish each message only after the graph has processed the last")
        start_s: float = param(0.0, min=0.0, doc="skip this much of the recording [s]")
        duration_s: float = param(0.0, min=0.0, doc="play only this much [s]; 0 = to the end")
        topics: tuple[str, ...] = param((), doc="recorded topics to play; empty = all")
        remap: tuple[str, ...] = param((), check=_remap_problem, doc="topic renames, from:=to")
        max_lag_s: float = param(0.05, min=0.0, doc="lag beyond which the schedule shifts [s]")

    @staticmethod
    def plays_lockstep(params: dict) -> bool:
        """Whether these (launch-file) params play in lockstep: ``lockstep: true`` or ``rate: 0``."""
        return bool(params.get("lockstep", False)) or params.get("rate", 1.0) == 0

    def setup(self) -> None:
        p = self.params
        # The read-ahead thread runs Python (record parsing) between publishes; with the default 5 ms
        # GIL switch interval a due publish could wait that long for the GIL.
        sys.setswitchinterval(min(sys.getswitchinterval(), GIL_SWITCH_S))
        self.remap = parse_remaps(p.remap)
        self.reader = BagReader(p.path)
        if self.reader.truncated:
            self.ctx.log.warning("%s: %s", p.path, self.reader.truncation_note)
        if self.reader.start_ns is None:
            raise BagError(f"{p.path}: no message to play"
                           + (f" ({self.reader.truncation_note})" if self.reader.truncated else ""))
        recorded = self._playable(self.reader.topics())
        check_schemas(p.path, {t: (i.type_name, i.version) for t, i in recorded.items()
                               if not p.topics or t in p.topics})
        missing = [t for t in p.topics if t not in recorded]
        if missing:
            raise ParamError(f"{p.path}: no topic(s) {missing} in the recording (has: {sorted(recorded)})",
                             node_id=self.ctx.node_id, key="topics")
        self.topics = list(p.topics) or sorted(recorded)
        self.lockstep = p.lockstep or p.rate == 0
        self.epoch = 0
        self.published = 0
        self.last_clock_ns: int | None = None
        self.timer = self.ctx.create_timer(0.001, self._step, name="play")
        self._restart()

    def _playable(self, recorded: dict) -> dict:
        """The probeless topics of the recording; other writers' channels (cdr, json, ...) are refused
        when asked for by name, else skipped with a warning naming them."""
        p = self.params
        foreign = {t: i.message_encoding for t, i in recorded.items() if i.foreign}
        asked = sorted(t for t in p.topics if t in foreign)
        if asked:
            raise ParamError(f"{p.path}: cannot play topic(s) {asked}: encoded as "
                             f"{sorted({foreign[t] for t in asked})}, not as probeless messages",
                             node_id=self.ctx.node_id, key="topics")
        if foreign and not p.topics:
            self.ctx.log.warning("%s: skipping %d topic(s) of other encodings: %s", p.path, len(foreign),
                                 ", ".join(f"{t} ({e})" for t, e in sorted(foreign.items())))
        return {t: i for t, i in recorded.items() if t not in foreign}

    def _corrupt(self, what: str) -> None:
        self.ctx.log.warning("%s", what)

    def _restart(self) -> None:
        p = self.params
        start = self.reader.start_ns + int(p.start_s * 1e9)
        end = start + int(p.duration_s * 1e9) if p.duration_s else None
        if getattr(self, "ahead", None) is not None:
            self.ahead.stop()
        self.ahead = ReadAhead(lambda: self.reader.messages(topics=self.topics, start_ns=start, end_ns=end,
                                                           on_corrupt=self._corrupt),
                               size=READ_AHEAD, name="bag-read-ahead")
        self.ahead.start()
        self.pending: BagMessage | None = None
        self.pacer = Pacer(p.rate) if p.rate > 0 else None
        self.first_log_ns = start

    def _step(self) -> None:
        """Publish every message that is due (the pacer sleeps precisely for one due very soon)."""
        while True:
            if self.pending is None:
                self.pending = self.ahead.next()
                if self.pending is None:
                    self._at_end()
                    return
            msg = self.pending
            if self.pacer is not None:
                lag = self.pacer.wait((msg.log_time_ns - self.first_log_ns) / 1e9)
                if lag is None:
                    self._tick_clock(time.monotonic(), self.params.rate)
                    return
                if lag > self.params.max_lag_s:
                    self.pacer.shift(lag)  # fell behind: slow every topic down together
            self._publish(msg)
            self.pending = None
            if self.lockstep:
                return  # one message per step: the node loop stays responsive to signals

    def _publish(self, msg: BagMessage) -> None:
        if self._clock(msg.log_time_ns) and self.lockstep:
            self.ctx.wait_quiescent()  # every node is at the new time before the data arrives
        self.ctx.publish_raw(self.remap.get(msg.topic, msg.topic), msg.frames[1:])
        self.published += 1
        if self.lockstep:
            self.ctx.wait_quiescent()

    def _tick_clock(self, now: float, rate: float) -> None:
        sim = self.first_log_ns + int((now - self.pacer.t0) * rate * 1e9)
        if self.last_clock_ns is None or sim - self.last_clock_ns >= CLOCK_PERIOD_NS:
            self._clock(sim)

    def _clock(self, stamp_ns: int) -> bool:
        """Publish the recorded time if it advanced; True when a clock message went out."""
        if self.last_clock_ns is not None and stamp_ns <= self.last_clock_ns:
            return False
        self.last_clock_ns = stamp_ns
        self.ctx.publish("clock", Clock(Header(stamp_ns, "clock"), self.params.rate, self.epoch))
        return True

    def close(self) -> None:
        if getattr(self, "ahead", None) is not None:
            self.ahead.stop()

    def _at_end(self) -> None:
        if not self.params.loop:
            self.timer.cancel()
            self.ctx.log.info("played %d message(s) from %s", self.published, self.params.path)
            self.ctx.stop()
            return
        self.epoch += 1
        self.last_clock_ns = None
        self._restart()
