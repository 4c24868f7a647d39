"""Image transform node: one OpenCV operation per frame, chosen by a param."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np

from probeless.messages.sensor import Image
from probeless.runtime import Node, param

OPERATIONS = ("blur", "edges", "gray", "invert")


def transform_image(rgb: np.ndarray, op: str, ksize: int = 5) -> np.ndarray:
    """Apply ``op`` to an RGB uint8 image (h, w, 3); returns (h, w, 3) uint8."""
    if op == "blur":
        return cv2.GaussianBlur(rgb, (ksize, ksize), 0)
    if op == "invert":
        return 255 - rgb
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    out = cv2.Canny(gray, 50, 150) if op == "edges" else gray
    return np.repeat(out[..., None], 3, axis=2)


class ImageTransform(Node):
    """Applies ``operation`` to every image on ``image`` and republishes it with the same stamp."""

    INPUTS = {"image": Image}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        operation: str = param("blur", choices=OPERATIONS, dynamic=True, doc="OpenCV operation to apply")
        ksize: int = param(5, min=1, max=99, check=lambda k: None if k % 2 else f"ksize must be odd, got {k}",
                           dynamic=True, doc="Gaussian kernel size for blur [px], odd")

    def on_input(self, name: str, msg: Image) -> None:
        with self.ctx.timed(f"op:{self.params.operation}"):
            out = transform_image(msg.data, self.params.operation, self.params.ksize)
        self.ctx.publish("image", dataclasses.replace(msg, data=out))
