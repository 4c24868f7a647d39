"""Small nodes used by the runtime tests (imported by node processes via PYTHONPATH=tests)."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from probeless.messages import Header, Image, NodeStatus, Tick
from probeless.runtime import Node, param


class Ticker(Node):
    """Publishes a 4x4 image per tick, with the frame index in pixel [0,0,0]; crashes at ``crash_at``."""

    INPUTS = {"tick": Tick}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        count: int = param(0, min=0)
        crash_at: int = param(-1)
        pid_file: str = param("")

    def setup(self):
        self.n = 0
        if self.params.pid_file:
            Path(self.params.pid_file).write_text(str(os.getpid()))

    def on_input(self, name, msg):
        if self.n == self.params.crash_at:
            raise ZeroDivisionError("crash requested by test")
        data = np.full((4, 4, 1), self.n % 256, np.uint8)
        self.ctx.publish("image", Image(Header(msg.header.stamp_ns, "t"), data, "mono8"))
        self.n += 1
        if self.params.count and self.n >= self.params.count:
            self.ctx.stop()


class FailsAtSetup(Node):
    """Fails in setup: with one of our errors (``error: ours``) or with a bug (``error: bug``)."""

    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        error: str = param("ours", choices=("ours", "bug"))

    def setup(self):
        if self.params.error == "ours":
            from probeless.errors import SceneError

            raise SceneError("nonexistent.yaml: scene file not found")
        raise KeyError("a bug in setup")


class Recorder(Node):
    """Records seq numbers per input (any name, any type); optionally slow; writes JSON on close."""

    INPUTS = {"*": None}

    @dataclass(frozen=True)
    class Params:
        out: str = param()
        sleep_ms: float = param(0.0, min=0)
        crash_once_marker: str = param("")
        pid_file: str = param("")

    def setup(self):
        if self.params.crash_once_marker and not Path(self.params.crash_once_marker).exists():
            Path(self.params.crash_once_marker).write_text("crashed")
            raise RuntimeError("first start fails on purpose")
        if self.params.pid_file:
            Path(self.params.pid_file).write_text(str(os.getpid()))
        self.seqs: dict[str, list[int]] = {}
        self.status: dict | None = None
        self.closed_inputs: list[str] = []

    def on_input(self, name, msg):
        if isinstance(msg, NodeStatus):
            self.status = {i.name: {"received": i.received, "dropped": i.dropped, "seq_gaps": i.seq_gaps,
                                    "queued": i.queued} for i in msg.inputs}
            return
        self.seqs.setdefault(name, []).append(msg.header.seq)
        if self.params.sleep_ms:
            time.sleep(self.params.sleep_ms / 1e3)

    def on_input_closed(self, name):
        self.closed_inputs.append(name)

    def close(self):
        Path(self.params.out).write_text(json.dumps(
            {"seqs": self.seqs, "status": self.status, "closed": self.closed_inputs}))


class Jitter(Node):
    """Republishes each image after a truly random sleep: a nondeterministically scheduled worker."""

    INPUTS = {"image": Image}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        max_sleep_ms: float = param(5.0, min=0)

    def on_input(self, name, msg):
        time.sleep(int.from_bytes(os.urandom(2), "little") / 65535 * self.params.max_sleep_ms / 1e3)
        self.ctx.publish("image", msg)


class ClockWatcher(Node):
    """Records ctx.now_ns() per message and counts on_time_reset calls; writes JSON on close."""

    INPUTS = {"*": None}

    @dataclass(frozen=True)
    class Params:
        out: str = param()

    def setup(self):
        self.now: list[int] = []
        self.stamps: list[int] = []
        self.recv_wall: list[int] = []
        self.resets = 0

    def on_input(self, name, msg):
        self.now.append(self.ctx.now_ns())
        self.stamps.append(msg.header.stamp_ns)
        self.recv_wall.append(time.time_ns())

    def on_time_reset(self):
        self.resets += 1

    def close(self):
        Path(self.params.out).write_text(json.dumps({"now": self.now, "stamps": self.stamps, "resets": self.resets,
                                                     "simulated": self.ctx.simulated_time,
                                                     "recv_wall": self.recv_wall}))


class TickRelay(Node):
    """Publishes Tick messages on an output named ``image`` (to provoke type mismatches on replay)."""

    INPUTS = {"tick": Tick}
    OUTPUTS = {"image": Tick}

    def on_input(self, name, msg):
        self.ctx.publish("image", msg)


class TickSink(Node):
    """Accepts only core/Tick on ``image``."""

    INPUTS = {"image": Tick}


class LoopRelay(Node):
    """Forwards ``image`` to ``out`` and counts what comes back on ``back`` (one half of a feedback loop)."""

    INPUTS = {"image": Image, "back": Image}
    OUTPUTS = {"out": Image}

    @dataclass(frozen=True)
    class Params:
        out: str = param("")

    def setup(self):
        self.counts = {"image": 0, "back": 0}

    def on_input(self, name, msg):
        self.counts[name] += 1
        if name == "image":
            self.ctx.publish("out", msg)

    def close(self):
        if self.params.out:
            Path(self.params.out).write_text(json.dumps(self.counts))


class ArrivalLog(Node):
    """Logs (seq, wall-clock arrival [ns]) per message on any input, and its own last diagnostics; JSON on close."""

    INPUTS = {"*": None}

    @dataclass(frozen=True)
    class Params:
        out: str = param()
        pid_file: str = param("")

    def setup(self):
        if self.params.pid_file:
            Path(self.params.pid_file).write_text(str(os.getpid()))
        self.log: dict[str, list[list[int]]] = {}
        self.status: dict = {}

    def on_input(self, name, msg):
        if isinstance(msg, NodeStatus):
            self.status[msg.node_id] = {i.name: {"received": i.received, "dropped": i.dropped,
                                                 "seq_gaps": i.seq_gaps, "queued_bytes": i.queued_bytes}
                                        for i in msg.inputs}
            return
        self.log.setdefault(name, []).append([msg.header.seq, time.time_ns()])

    def close(self):
        Path(self.params.out).write_text(json.dumps({"log": self.log, "status": self.status}))
