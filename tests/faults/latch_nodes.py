"""Test nodes of tests/faults/test_latched_topics.py (node processes import them via PYTHONPATH=tests/faults).

- ``StaticSource``: on its first tick publishes a floorplan (latched by default), an extrinsic pose on
  ``fisheye_from_rgbd`` (latched by default) and an image (not latched), once each; then idles.
- ``ArrivalLines``: appends one JSON line per received message to ``out`` at once (a SIGKILLed process leaves
  its lines), with the process id, the input, the seq and the payload that identifies the message.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass

import numpy as np

from probeless.messages import Header, Image, Tick
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.runtime import Node, param


class StaticSource(Node):
    """Publishes ``floorplan``, ``fisheye_from_rgbd`` and ``image`` once, at the first tick."""

    INPUTS = {"tick": Tick}
    OUTPUTS = {"floorplan": Floorplan, "fisheye_from_rgbd": PoseStamped, "image": Image}

    @dataclass(frozen=True)
    class Params:
        width_m: float = param(4.0, min=0.1)
        ceiling_m: float = param(2.5, min=0.1)

    def setup(self):
        self.done = False

    def on_input(self, name, msg):
        if self.done:
            return
        self.done = True
        w = self.params.width_m
        verts = np.array([[0.0, 0.0], [w, 0.0], [w, 3.0], [0.0, 3.0]])
        self.ctx.publish("floorplan", Floorplan(Header(1, "world"), verts, self.params.ceiling_m))
        T = np.eye(4)
        T[:3, 3] = [0.0, -0.06, -0.02]
        self.ctx.publish("fisheye_from_rgbd", PoseStamped(Header(1, "rgbd"), "fisheye", T))
        self.ctx.publish("image", Image(Header(1, "cam"), np.full((2, 2, 1), 7, np.uint8), "mono8"))
        self.ctx.log.info("published the static messages")


class ArrivalLines(Node):
    """One JSON line per message: pid, wall-clock time, input, type, seq, and the floorplan / pose / image payload."""

    INPUTS = {"*": None}

    @dataclass(frozen=True)
    class Params:
        out: str = param()

    def setup(self):
        self.file = open(self.params.out, "a", buffering=1)  # line-buffered: each line is written at once
        self._line({"event": "setup"})

    def on_input(self, name, msg):
        line = {"event": "message", "input": name, "type": msg.TYPE_NAME, "seq": msg.header.seq,
                "stamp_ns": msg.header.stamp_ns}
        if isinstance(msg, Floorplan):
            line.update(vertices=msg.vertices.tolist(), ceiling=msg.ceiling_height)
        elif isinstance(msg, PoseStamped):
            line.update(T=msg.target_from_source.tolist())
        elif isinstance(msg, Image):
            line.update(pixel=int(msg.data.flat[0]))
        self._line(line)

    def _line(self, line: dict) -> None:
        self.file.write(json.dumps({"pid": os.getpid(), "t_ns": time.time_ns(), **line}) + "\n")

    def close(self):
        self.file.close()
