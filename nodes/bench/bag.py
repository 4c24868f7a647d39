"""Nodes of the recording benchmark (``probeless bench bag``), registered as ``bench_camera_source``,
``bench_timing_source``, ``bench_timing_sink`` and ``bench_jitter_worker``.

* ``CameraSource``: an RGB-D camera (640x480 rgb8 + uint16 depth) at ``rate_hz`` and a 1024x1024 rgb8
  fisheye at half that rate; or, with ``max_rate``, the same message mix back to back (blocking on the
  recorder's ``block`` inputs). Frames are realistic and not trivially compressible (smooth scene +
  sensor noise, depth holes, a black fisheye border) and move from frame to frame; they are made once
  in ``setup`` (``variants`` shifted copies, cycled), so publishing costs no CPU for content.
* ``TimingSource``: small images at random (seeded) 5-30 ms intervals, to record a known irregular timing.
* ``TimingSink``: raw input (nothing decoded), keeps the receiver thread's receive time of every message.
* ``JitterWorker``: sleeps a truly random time (``os.urandom`` seed) per message, then publishes a
  transformed copy: two of them fed by one source make the arrival order downstream vary run to run.

Sources, the sink and workers write what they measured as JSON to ``out_path`` in ``close()``.
"""

from __future__ import annotations

import json
import os
import random
import time
from dataclasses import dataclass

from probeless.datasets.synthetic_frames import camera_frames, camera_message
from probeless.messages.header import Header
from probeless.messages.sensor import DepthImage, Image
from probeless.runtime import Node, param

CAMERA_TOPICS = ("rgb", "depth", "fisheye")   # outputs of CameraSource, in publishing order


def _write_json(path: str, data: dict) -> None:
    if not path:
        return
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(data, f)
    os.replace(tmp, path)


class CameraSource(Node):
    """RGB + depth every tick, fisheye every other tick; ``ticks`` ticks at ``rate_hz`` or back to back."""

    OUTPUTS = {"rgb": Image, "depth": DepthImage, "fisheye": Image}

    @dataclass(frozen=True)
    class Params:
        ticks: int = param(60, min=1, doc="ticks to publish (rgb+depth each, fisheye every other one)")
        rate_hz: float = param(30.0, min=0.1, max=10000.0, doc="tick rate of the real-time mode [Hz]")
        max_rate: bool = param(False, doc="publish back to back instead of at rate_hz")
        width: int = param(640, min=1, max=8192, doc="RGB-D width [px]")
        height: int = param(480, min=1, max=8192, doc="RGB-D height [px]")
        fisheye_size: int = param(1024, min=1, max=8192, doc="fisheye width = height [px]")
        variants: int = param(8, min=1, max=64, doc="distinct (shifted) frames per stream, cycled")
        out_path: str = param("", doc="JSON file the publish counts and times are written to")

    def setup(self) -> None:
        p = self.params
        sizes = {"rgb": (p.width, p.height), "depth": (p.width, p.height),
                 "fisheye": (p.fisheye_size, p.fisheye_size)}
        self.frames = {k: camera_frames(k, *sizes[k], p.variants) for k in CAMERA_TOPICS}
        self.tick = 0
        self.published = {k: 0 for k in CAMERA_TOPICS}
        self.first_ns = self.last_ns = 0
        period = 1e-6 if p.max_rate else 1.0 / p.rate_hz
        self.timer = self.ctx.create_timer(period, self._on_timer, name="camera")

    def _on_timer(self) -> None:
        for _ in range(16 if self.params.max_rate else 1):  # a burst, then back to the loop (signals)
            self._publish_tick()
            if self.tick >= self.params.ticks:
                self.timer.cancel()
                self.ctx.stop()
                return

    def _publish_tick(self) -> None:
        now = time.time_ns()
        if not self.first_ns:
            self.first_ns = now
        i = self.tick
        for kind in CAMERA_TOPICS:
            if kind == "fisheye" and i % 2:
                continue
            frames = self.frames[kind]
            self.ctx.publish(kind, camera_message(kind, frames[i % len(frames)], now))
            self.published[kind] += 1
        self.tick += 1
        self.last_ns = time.time_ns()

    def close(self) -> None:
        _write_json(self.params.out_path, {
            "published": self.published, "ticks": self.tick, "first_ns": self.first_ns, "last_ns": self.last_ns,
            "missed_ticks": int(getattr(self.timer, "missed_total", 0)) if not self.params.max_rate else 0})


class TimingSource(Node):
    """``count`` small images at random intervals uniform in [min_ms, max_ms] (seeded, repeatable)."""

    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        count: int = param(600, min=1, doc="messages to publish")
        min_ms: float = param(5.0, min=0.0, doc="shortest interval [ms]")
        max_ms: float = param(30.0, min=0.0, doc="longest interval [ms]")
        width: int = param(320, min=1, max=8192, doc="image width [px]")
        height: int = param(240, min=1, max=8192, doc="image height [px]")
        seed: int = param(1, doc="seed of the intervals")

    def setup(self) -> None:
        p = self.params
        self.rng = random.Random(p.seed)
        self.frames = camera_frames("rgb", p.width, p.height, 8)
        self.sent = 0
        self.due_ns: int | None = None
        self.timer = self.ctx.create_timer(0.0005, self._on_timer, name="timing")

    def _on_timer(self) -> None:
        now = time.monotonic_ns()
        if self.due_ns is None:
            self.due_ns = now
        if now < self.due_ns:
            return
        self.ctx.publish("image", Image(Header(self.ctx.now_ns(), "timing"), self.frames[self.sent % 8], "rgb8"))
        self.sent += 1
        self.due_ns = now + int(self.rng.uniform(self.params.min_ms, self.params.max_ms) * 1e6)
        if self.sent >= self.params.count:
            self.timer.cancel()
            self.ctx.stop()


class TimingSink(Node):
    """Keeps (header.seq, receive wall time [ns]) of every message; raw input, nothing decoded."""

    INPUTS = {"image": Image}
    RAW_INPUTS = True

    @dataclass(frozen=True)
    class Params:
        out_path: str = param(doc="JSON file the receive times are written to")

    def setup(self) -> None:
        self.seqs: list[int] = []
        self.recv_ns: list[int] = []

    def on_input(self, name: str, msg) -> None:
        self.seqs.append(msg.seq)
        self.recv_ns.append(msg.recv_ns)  # stamped by the receiver thread as the frames arrived

    def close(self) -> None:
        _write_json(self.params.out_path, {"seqs": self.seqs, "recv_ns": self.recv_ns})


class JitterWorker(Node):
    """Sleeps uniform [0, max_sleep_ms] (truly random per run), then publishes a transformed copy."""

    INPUTS = {"image": Image}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        max_sleep_ms: float = param(2.0, min=0.0, doc="longest random sleep per message [ms]")
        operation: str = param("invert", choices=("invert", "halve"), doc="what is published")
        out_path: str = param("", doc="JSON file the processing times are written to")

    def setup(self) -> None:
        self.rng = random.Random(os.urandom(16))
        self.count = 0
        self.slept_s = 0.0
        self.first_ns = self.last_ns = 0

    def on_input(self, name: str, msg: Image) -> None:
        now = time.monotonic_ns()
        if not self.first_ns:
            self.first_ns = now
        self.last_ns = now
        pause = self.rng.uniform(0.0, self.params.max_sleep_ms) / 1e3
        time.sleep(pause)
        self.slept_s += pause
        data = 255 - msg.data if self.params.operation == "invert" else msg.data // 2
        self.ctx.publish("image", Image(Header(msg.header.stamp_ns, self.ctx.node_id), data, msg.encoding))
        self.count += 1

    def close(self) -> None:
        _write_json(self.params.out_path, {"count": self.count, "slept_s": self.slept_s,
                                           "first_ns": self.first_ns, "last_ns": self.last_ns})
