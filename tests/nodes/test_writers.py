"""video_writer and png_writer nodes: what they write reads back with OpenCV."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from probeless.errors import NodeError
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.output.writers import PngWriter, VideoWriter
from probeless.runtime.testing import run_node


def _frames(n, w=64, h=48):
    for i in range(n):
        img = np.zeros((h, w, 3), np.uint8)
        img[:, :, 0] = 40 * i % 256  # red ramps over time
        img[: h // 2, :, 2] = 200     # blue top half
        yield "image", Image(Header(i * 1000, "cam"), img, "rgb8")


def test_video_writer_round_trip(tmp_path):
    path = tmp_path / "sub" / "out.mp4"
    frames = list(_frames(6))
    frames.append(("image", Image(Header(9, "cam"), np.zeros((24, 32, 3), np.uint8), "rgb8")))  # other size
    run_node(VideoWriter, frames, {"path": str(path), "fps": 10.0})
    cap = cv2.VideoCapture(str(path))
    read = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        read.append(f)
    assert len(read) == 7 and read[0].shape == (48, 64, 3)
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(10.0)
    # lossy codec: colours close to the input (BGR order on read)
    assert abs(int(read[3][5, 5, 2]) - 120) < 20 and read[3][40, 5, 0] < 30 and read[3][5, 5, 0] > 170


def test_png_writer_every_and_last(tmp_path):
    run_node(PngWriter, _frames(5), {"out_dir": str(tmp_path), "every": 2})
    names = sorted(p.name for p in tmp_path.glob("*.png"))
    assert names == ["frame_000000.png", "frame_000002.png", "frame_000004.png", "frame_last.png"]
    last = cv2.imread(str(tmp_path / "frame_last.png"))
    assert tuple(last[0, 0]) == (200, 0, 160)  # BGR of rgb (160, 0, 200): lossless


def test_writer_rejects_16_bit(tmp_path):
    img = Image(Header(0, "cam"), np.zeros((4, 4, 1), np.uint16), "mono16")
    with pytest.raises(NodeError, match="only 8-bit"):
        run_node(PngWriter, [("image", img)], {"out_dir": str(tmp_path)})
