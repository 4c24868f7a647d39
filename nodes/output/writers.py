"""Writer nodes: ``video_writer`` (Image stream -> MP4) and ``png_writer`` (Image stream -> PNG files).

Both accept rgb8, bgr8, rgba8 and mono8 images. The video's size is fixed by its first frame; a
frame of another size is resized to it (counted, logged once) rather than dropped, so no frame of
the stream is lost. The video's frame rate is a param (stamps are not used for timing).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from probeless.errors import NodeError
from probeless.messages.sensor import Image
from probeless.runtime import Node, param
from probeless.runtime.params import writable_dir_problem, writable_file_problem


def to_bgr(msg: Image) -> np.ndarray:
    """An Image message as a BGR uint8 array for OpenCV."""
    data = np.asarray(msg.data)
    if data.dtype != np.uint8:
        raise NodeError(f"image encoding {msg.encoding!r}: only 8-bit images can be written")
    conv = {"rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR, "bgra8": cv2.COLOR_BGRA2BGR,
            "mono8": cv2.COLOR_GRAY2BGR}
    if msg.encoding == "bgr8":
        return np.ascontiguousarray(data)
    if msg.encoding not in conv:
        raise NodeError(f"image encoding {msg.encoding!r} cannot be written (rgb8, bgr8, rgba8, bgra8, mono8)")
    return cv2.cvtColor(data, conv[msg.encoding])


class VideoWriter(Node):
    """Writes every ``image`` to an MP4 file (OpenCV, codec ``mp4v``)."""

    INPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        path: str = param(check=writable_file_problem, doc="output .mp4 file (parent folders are created)")
        fps: float = param(15.0, min=0.1, max=1000.0, doc="frame rate written into the file [Hz]")
        codec: str = param("mp4v", length=4, doc="FourCC of the codec (4 characters)")

    def setup(self) -> None:
        self.writer: cv2.VideoWriter | None = None
        self.size: tuple[int, int] | None = None
        self.counts: Counter[str] = Counter()
        Path(self.params.path).parent.mkdir(parents=True, exist_ok=True)

    def on_input(self, name: str, msg: Image) -> None:
        frame = to_bgr(msg)
        h, w = frame.shape[:2]
        if self.writer is None:
            fourcc = cv2.VideoWriter_fourcc(*self.params.codec)
            self.writer = cv2.VideoWriter(self.params.path, fourcc, self.params.fps, (w, h))
            if not self.writer.isOpened():
                raise NodeError(f"cannot open {self.params.path} for writing with codec {self.params.codec!r}")
            self.size = (w, h)
        if (w, h) != self.size:
            if not self.counts["resized"]:
                self.ctx.log.warning("frame %dx%d resized to the video's %dx%d", w, h, *self.size)
            self.counts["resized"] += 1
            frame = cv2.resize(frame, self.size, interpolation=cv2.INTER_AREA)
        self.writer.write(frame)
        self.counts["frames"] += 1

    def close(self) -> None:
        if getattr(self, "writer", None) is not None:
            self.writer.release()
            self.ctx.log.info("wrote %s: %s", self.params.path, dict(self.counts))


class PngWriter(Node):
    """Writes each ``image`` as ``<prefix><seq>.png`` (every n-th), and the last one as ``<prefix>last.png``."""

    INPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        out_dir: str = param(check=writable_dir_problem, doc="output folder (created)")
        prefix: str = param("frame_", doc="file name prefix")
        every: int = param(1, min=0, max=10**9, doc="write every n-th frame; 0 = only the last")

    def setup(self) -> None:
        self.out = Path(self.params.out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self.n = 0
        self.last: np.ndarray | None = None

    def on_input(self, name: str, msg: Image) -> None:
        self.last = to_bgr(msg)
        if self.params.every and self.n % self.params.every == 0:
            cv2.imwrite(str(self.out / f"{self.params.prefix}{self.n:06d}.png"), self.last)
        self.n += 1

    def close(self) -> None:
        if getattr(self, "last", None) is not None:
            cv2.imwrite(str(self.out / f"{self.params.prefix}last.png"), self.last)
