"""Fisheye player: plays an image folder or a video file as the rig's fisheye camera.

Outputs: ``fisheye`` (Image rgb8 or mono8) and ``fisheye/camera_info`` (the ``calibration`` file,
our YAML or OCamCalib calib_results.txt, published with every frame just before it). The
calibration must be for the footage's image size, else setup fails naming both. Stamps: a
``stamps`` file (seconds, one per frame) or frame / fps, plus ``time_offset_s`` (``stamps_mode: wall``:
the node clock when published). Pacing as the
RGB-D player: ``rate`` scales the recorded timing, ``rate: 0`` is lockstep.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Iterator

from probeless.datasets.fisheye import COLORS, FisheyeFootage, first_frame_size, fisheye_frames, open_fisheye
from probeless.datasets.playback import STAMPS, Group, Playback
from probeless.datasets.stream import loop_period_ns
from probeless.errors import CalibrationError, DatasetError
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo, Image
from probeless.runtime import Node, param


def load_fisheye_calibration(path: str, footage: FisheyeFootage, frame_id: str) -> CameraInfo:
    """The calibration at ``path`` checked against the footage's frame size (DatasetError on mismatch)."""
    from probeless.cameras.io import load_calibration

    w, h = first_frame_size(footage)
    try:
        info = load_calibration(path, width=w, height=h, frame_id=frame_id)
    except CalibrationError as exc:
        raise DatasetError(f"calibration {path} does not fit {footage.path} ({w}x{h} frames): {exc}") from exc
    if (info.width, info.height) != (w, h):
        raise DatasetError(f"calibration {path} is for {info.width}x{info.height} images, "
                           f"{footage.path} has {w}x{h} frames")
    return info


def fisheye_groups(footage: FisheyeFootage, info: CameraInfo, frame_id: str = "fisheye",
                   color: str = "auto", offset_ns: int = 0) -> Iterator[Group]:
    """One group per frame: ``fisheye/camera_info`` then ``fisheye``, stamps shifted by ``offset_ns``."""
    for stamp, data, encoding in fisheye_frames(footage, color):
        header = Header(stamp + offset_ns, frame_id)
        yield stamp + offset_ns, [("fisheye/camera_info", dataclasses.replace(info, header=header)),
                                  ("fisheye", Image(header, data, encoding))]


class FisheyePlayer(Node):
    """Publishes fisheye footage from disk with its calibration (see the module docstring)."""

    OUTPUTS = {"fisheye": Image, "fisheye/camera_info": CameraInfo}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="any", must_exist=True, doc="image folder or video file")
        calibration: str = param(path="file", must_exist=True,
                                 doc="calibration file: our YAML or OCamCalib calib_results.txt")
        stamps: str = param("", path="file", must_exist=True,
                            doc="file with one stamp [s] per frame; empty = frame / fps")
        fps: float = param(0.0, min=0.0, doc="frame rate without stamps [Hz]; 0 = the video's, or 30 for a folder")
        time_offset_s: float = param(0.0, doc="added to every stamp [s]")
        rate: float = param(1.0, min=0.0, max=1000.0, doc="speed factor of the recorded timing; 0 = lockstep")
        loop: bool = param(False, doc="start again at the end")
        color: str = param("auto", choices=COLORS, doc="output encoding; auto = mono8 for grey files, else rgb8")
        frame_id: str = param("fisheye", doc="frame_id of the images")
        stamps_mode: str = param("dataset", choices=STAMPS,
                                 doc="dataset = the footage's stamps; wall = the node clock at publishing")

    def setup(self) -> None:
        p = self.params
        footage = open_fisheye(p.path, stamps=p.stamps or None, fps=p.fps, time_offset_s=p.time_offset_s)
        self.footage = footage
        self.info = load_fisheye_calibration(p.calibration, footage, p.frame_id)
        self.first_pass: list[int] = []  # stamps of pass 0, for the stamp offset of later passes
        self.playback = Playback(self.ctx, self._pass, rate=p.rate, loop=p.loop, what="fisheye frames",
                                 stamps=p.stamps_mode)

    def _pass(self, k: int) -> Iterator[Group]:
        """Pass ``k`` (runs on the read-ahead thread; pass k > 0 starts after pass 0 has ended)."""
        p = self.params
        offset = k * loop_period_ns(self.first_pass, self.footage.fps) if k else 0
        for group in fisheye_groups(self.footage, self.info, p.frame_id, p.color, offset):
            if k == 0:
                self.first_pass.append(group[0])
            yield group

    def close(self) -> None:
        if getattr(self, "playback", None) is not None:
            self.playback.close()
