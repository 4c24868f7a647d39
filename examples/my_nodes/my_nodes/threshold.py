"""A node type shipped by a separate package: binary threshold of an image's grey level."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from probeless.messages.sensor import Image
from probeless.runtime import Node, param


def threshold(rgb: np.ndarray, level: int) -> np.ndarray:
    """White where the grey level of ``rgb`` (H x W x 3, uint8) is above ``level``, else black; RGB out."""
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    _, mask = cv2.threshold(gray, level, 255, cv2.THRESH_BINARY)
    return cv2.cvtColor(mask, cv2.COLOR_GRAY2RGB)


class Threshold(Node):
    """Binary threshold of every ``image`` (rgb8) at grey level ``level``, republished with the same stamp."""

    INPUTS = {"image": Image}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        level: int = param(127, min=0, max=255, doc="grey level above which a pixel turns white [0-255]")

    def on_input(self, name: str, msg: Image) -> None:
        self.ctx.publish("image", Image(msg.header, threshold(msg.data, self.params.level), msg.encoding))
