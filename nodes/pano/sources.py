"""Panorama source nodes: a 360° video played at its frame rate, and a still panorama repeated.

``Video360Source`` publishes ``image`` (rgb8, equirectangular) decoded on a background thread
(:class:`~probeless.pano.sources.VideoFrames`); frame k is due at ``t0 + video_time_k / rate``.
It drops nothing by default: a frame published more than ``max_lag_s`` late is counted in ``late``
and the schedule shifts; with ``drop_late`` such frames are skipped instead (counted in ``dropped``).
``rate: 0`` is lockstep (each frame after the graph is idle). Stamps: video time, increasing
across loops, or the node clock (``stamps: wall``).

``PanoramaSource`` reads one still panorama and publishes it every ``1 / rate_hz`` seconds:
HDR files (and LDR ones with ``linear``) as ``hdr`` (rgbf32, linear), LDR files as ``image`` (rgb8).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.pano.sources import HDR_SUFFIXES, LDR_SUFFIXES, VideoFrames, equirect_ok, read_panorama
from probeless.runtime import Node, param
from probeless.runtime.pacing import Pacer


class Video360Source(Node):
    """Plays an equirectangular video file on ``image`` (see the module docstring)."""

    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="file", must_exist=True,
                          doc="equirectangular video file (anything OpenCV/FFmpeg decodes)")
        loop: bool = param(False, doc="start again at the end")
        rate: float = param(1.0, min=0.0, max=1000.0, doc="speed factor of the video timing; 0 = lockstep")
        max_frames: int = param(0, min=0, doc="stop after this many frames; 0 = at the end of the video")
        fps: float = param(0.0, min=0.0, doc="frame rate [Hz]; 0 = the container's")
        stamps: str = param("video", choices=("video", "wall"), doc="video time or the node clock at publishing")
        max_lag_s: float = param(0.05, min=0.0, doc="lateness beyond which a frame counts as late [s]")
        drop_late: bool = param(False, doc="skip late frames instead of shifting the schedule")
        check_equirect: bool = param(True, doc="fail unless width == 2 x height")
        frame_id: str = param("pano", doc="frame_id of the images")

    def setup(self) -> None:
        p = self.params
        self.video = VideoFrames(p.path, loop=p.loop, fps=p.fps)
        if p.check_equirect:
            equirect_ok((self.video.height, self.video.width), p.path)
        self.video.start()
        self.published = self.late = self.dropped = 0
        self.pending = None
        self.pacer = Pacer(p.rate) if p.rate > 0 else None
        self.loop_offset_s = 0.0  # video time of the start of the current pass
        self.last_t_s = -1.0
        self.timer = self.ctx.create_timer(0.001, self.step, name="play")

    def step(self) -> None:
        """Publish every frame that is due (lockstep: at most one per call); never waits for the decoder."""
        p = self.params
        while True:
            if self.pending is None:
                frame = self.video.poll()
                if frame is None:
                    if self.video.ended:
                        self._finish()
                    return
                index, t_s, rgb = frame
                if index == 0 and self.last_t_s >= 0:  # a new pass of a looped video
                    self.loop_offset_s += self.last_t_s + 1.0 / self.video.fps
                self.last_t_s = t_s
                self.pending = (self.loop_offset_s + t_s, rgb)
            vt, rgb = self.pending
            if self.pacer is not None:
                lag = self.pacer.wait(vt)
                if lag is None:
                    return
                if lag > p.max_lag_s:
                    if p.drop_late:
                        self.dropped += 1
                        self.pending = None
                        continue
                    self.late += 1
                    self.pacer.shift(lag)  # fell behind: slow down instead of bursting
            else:
                self.ctx.wait_quiescent()
            stamp = self.ctx.now_ns() if p.stamps == "wall" else round(vt * 1e9)
            self.ctx.publish("image", Image(Header(stamp, p.frame_id), rgb, "rgb8"))
            self.published += 1
            self.pending = None
            if p.max_frames and self.published >= p.max_frames:
                self._finish()
                return
            if p.rate == 0:
                return

    def _finish(self) -> None:
        self.timer.cancel()
        self.ctx.log.info("played %d frame(s) of %s (%d late, %d dropped)", self.published, self.params.path,
                          self.late, self.dropped)
        self.ctx.stop()

    def close(self) -> None:
        if getattr(self, "video", None) is not None:
            self.video.close()


def _panorama_type_problem(path: str) -> str | None:
    """The panorama path's rule (a param check): a file type read_panorama reads."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in HDR_SUFFIXES + LDR_SUFFIXES:
        return f"{path}: unknown panorama type {suffix!r}, expected one of {HDR_SUFFIXES + LDR_SUFFIXES}"
    return None


class PanoramaSource(Node):
    """Publishes one still panorama repeatedly (see the module docstring)."""

    OUTPUTS = {"image": Image, "hdr": Image}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="file", must_exist=True, check=_panorama_type_problem,
                          doc="panorama: Radiance .hdr, .exr (if OpenCV has it), .png or .jpg")
        rate_hz: float = param(1.0, min=1e-3, max=1000.0, doc="publishing rate [Hz]")
        count: int = param(0, min=0, doc="publish this many times, then stop; 0 = until stopped")
        linear: bool = param(False, doc="LDR files: linearise sRGB and publish rgbf32 on hdr")
        check_equirect: bool = param(True, doc="fail unless width == 2 x height")
        frame_id: str = param("pano", doc="frame_id of the images")

    def setup(self) -> None:
        p = self.params
        data = read_panorama(p.path, linear=p.linear)
        if p.check_equirect:
            equirect_ok(data.shape, p.path)
        data.setflags(write=False)  # the same array goes out every time
        self.data = data
        self.output, self.encoding = ("hdr", "rgbf32") if data.dtype.kind == "f" else ("image", "rgb8")
        self.published = 0
        self.timer = self.ctx.create_timer(1.0 / p.rate_hz, self.tick, name="panorama")

    def tick(self) -> None:
        """Publish the panorama once; stop after ``count``."""
        p = self.params
        self.ctx.publish(self.output, Image(Header(self.ctx.now_ns(), p.frame_id), self.data, self.encoding))
        self.published += 1
        if p.count and self.published >= p.count:
            self.timer.cancel()
            self.ctx.stop()
