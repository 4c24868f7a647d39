"""Live camera driver through OpenCV ``VideoCapture``: a USB/UVC device index, a network URL or a file.

Outputs ``image`` (rgb8, or mono8 for a grey stream) and, with a ``calibration`` file, ``camera_info``
(published with every frame just before it; the calibration must be for the capture's size).

Stamps: live sources get the host wall clock ``time.time_ns()`` when ``grab()`` returns (so they
include the transfer latency; ``time_offset_s`` can subtract a known one). Files get
``t_open + CAP_PROP_POS_MSEC`` and, with ``realtime``, are delivered at that pace like a camera;
at the end of a file the node stops cleanly, with a warning when it delivered fewer frames than the
file's header announces (a truncated or corrupt file: the readable prefix is published). A capture
thread reads frames so the node's thread is never blocked; for live sources it keeps only the newest
``buffer`` frames (drops are counted and logged). A device that cannot be opened, fails a read or
delivers nothing for ``timeout_s`` raises DeviceError naming it.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import cv2

from probeless.datasets.capture import CaptureSettings, capture_frames, frame_image, is_file, open_capture, parse_device
from probeless.datasets.framethread import FrameThread, drain
from probeless.errors import CalibrationError, DeviceError
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo, Image
from probeless.runtime import Node, param


class OpenCvCamera(Node):
    """Publishes the frames of an OpenCV VideoCapture source (see the module docstring)."""

    OUTPUTS = {"image": Image, "camera_info": CameraInfo}

    @dataclass(frozen=True)
    class Params:
        device: int | str = param(0, doc="device index, video file path or stream URL")
        width: int = param(0, min=0, doc="requested width [px]; 0 = device default")
        height: int = param(0, min=0, doc="requested height [px]; 0 = device default")
        fps: float = param(0.0, min=0.0, doc="requested frame rate [Hz]; 0 = device default")
        exposure: float | None = param(None, doc="manual exposure in the backend's units; None = auto")
        fourcc: str = param("", doc="pixel format, e.g. MJPG; empty = device default")
        frame_id: str = param("camera", doc="frame_id of the images")
        calibration: str = param("", path="file", must_exist=True,
                                 doc="calibration file (our YAML or OCamCalib); empty = no camera_info")
        time_offset_s: float = param(0.0, doc="added to every stamp [s], e.g. minus a known latency")
        realtime: bool = param(True, doc="files: deliver frames at their recorded pace")
        buffer: int = param(2, min=1, max=1000, doc="live: newest frames kept while the node is busy")
        timeout_s: float = param(5.0, min=0.1, doc="live: DeviceError after this long without a frame [s]")

    def setup(self) -> None:
        p = self.params
        device = parse_device(p.device)
        self.file = is_file(device)
        cap = open_capture(device, CaptureSettings(p.width, p.height, p.fps, p.exposure, p.fourcc))
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        self.info = None
        if p.calibration:
            from probeless.cameras.io import load_calibration

            try:
                self.info = load_calibration(p.calibration, width=w, height=h, frame_id=p.frame_id)
            except CalibrationError as exc:
                cap.release()
                raise DeviceError(f"camera {p.device!r} gives {w}x{h} frames; "
                                  f"calibration {p.calibration}: {exc}") from exc
        self.offset_ns = round(p.time_offset_s * 1e9)
        self.reported_drops = 0
        self.announced = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if self.file else 0  # <= 0: unknown
        self.published = 0
        frames = capture_frames(cap, p.device, file=self.file)
        self.thread = FrameThread(frames, f"capture-{p.device}", wait=self.file, pace=self.file and p.realtime,
                                  buffer=p.buffer, on_exit=cap.release)
        self.timer = self.ctx.create_timer(0.002, self.poll, name="capture")

    def poll(self) -> None:
        """Publish the frames the capture thread has queued; stop at a file's end; raise its errors."""
        if self.thread.ident is None:  # capture starts with the graph (timers fire only after the start)
            self.last_frame = time.monotonic()
            self.thread.start()
        if drain(self.thread, self.publish):
            self.timer.cancel()
            if self.published < self.announced:
                self.ctx.log.warning("camera %r: the file ended after %d of the %d frame(s) its header announces "
                                     "(truncated or corrupt?)", self.params.device, self.published, self.announced)
            self.ctx.stop()
            return
        if self.thread.dropped > self.reported_drops:
            self.ctx.log.warning("camera %r: %d frame(s) dropped while the node was busy",
                                 self.params.device, self.thread.dropped - self.reported_drops)
            self.reported_drops = self.thread.dropped
        if not self.file and time.monotonic() - self.last_frame > self.params.timeout_s:
            raise DeviceError(f"camera {self.params.device!r}: no frame for {self.params.timeout_s} s")

    def publish(self, stamp_ns: int, frame) -> None:
        self.last_frame = time.monotonic()
        header = Header(stamp_ns + self.offset_ns, self.params.frame_id)
        data, encoding = frame_image(frame, f"camera {self.params.device!r}")
        if self.info is not None:
            self.ctx.publish("camera_info", dataclasses.replace(self.info, header=header))
        self.ctx.publish("image", Image(header, data, encoding))
        self.published += 1

    def close(self) -> None:
        if getattr(self, "thread", None) is not None:
            if self.thread.ident is None:
                self.thread.on_exit()  # never started: release the device here
            self.thread.stop()
            if self.thread.ident is not None:
                self.thread.join(2.0)
