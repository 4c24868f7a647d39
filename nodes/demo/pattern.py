"""Synthetic image source: a moving colour pattern with a known analytic form, one frame per tick."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.messages.header import Header, Tick
from probeless.messages.sensor import Image
from probeless.runtime import Node, param


def pattern_image(width: int, height: int, frame: int) -> np.ndarray:
    """RGB uint8 test pattern: horizontal red ramp, vertical green ramp, blue square moving with ``frame``."""
    x = np.linspace(0, 255, width, dtype=np.float32)
    y = np.linspace(0, 255, height, dtype=np.float32)
    img = np.zeros((height, width, 3), np.uint8)
    img[..., 0] = x[None, :].astype(np.uint8)
    img[..., 1] = y[:, None].astype(np.uint8)
    side = max(1, min(width, height) // 6)
    x0 = (frame * 7) % max(1, width - side)
    y0 = (frame * 5) % max(1, height - side)
    img[y0:y0 + side, x0:x0 + side, 2] = 255
    return img


class PatternSource(Node):
    """Publishes ``pattern_image`` on ``image`` at each ``tick``; stops after ``count`` frames (0 = never)."""

    INPUTS = {"tick": Tick}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        width: int = param(320, min=1, max=8192, doc="image width [px]")
        height: int = param(240, min=1, max=8192, doc="image height [px]")
        count: int = param(0, min=0, doc="frames to publish before stopping; 0 = run until stopped")
        frame_id: str = param("pattern", doc="frame_id of the published images")

    def setup(self) -> None:
        self.frame = 0

    def on_input(self, name: str, msg: Tick) -> None:
        p = self.params
        data = pattern_image(p.width, p.height, self.frame)
        self.ctx.publish("image", Image(Header(msg.header.stamp_ns, p.frame_id), data, "rgb8"))
        self.frame += 1
        if p.count and self.frame >= p.count:
            self.ctx.stop()
