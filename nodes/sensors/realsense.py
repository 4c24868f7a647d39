"""Intel RealSense driver through Open3D's ``open3d.t.io.RealSenseSensor``.

Outputs as the RGB-D dataset player: ``rgb`` (rgb8), ``depth`` (uint16, aligned to the colour
image, the device's depth scale), ``rgbd/camera_info`` (the colour intrinsics, with every frame).
No ``gt/rgbd_pose``. Without a connected device, setup raises DeviceError. Stamps: host wall clock
``time.time_ns()`` when ``capture_frame`` returns (like the OpenCV driver). A capture thread
keeps the newest ``buffer`` frames while the node is busy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from probeless.datasets.base import Intrinsics, camera_info
from probeless.datasets.framethread import FrameThread, drain
from probeless.errors import DeviceError
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.runtime import Node, param


def realsense_devices() -> list:
    """Connected RealSense cameras (Open3D ``RealSenseSensor.enumerate_devices``); DeviceError if none."""
    try:
        from open3d.t.io import RealSenseSensor
    except ImportError as exc:
        raise DeviceError(f"RealSense: open3d without RealSense support ({exc})") from exc
    devices = list(RealSenseSensor.enumerate_devices())
    if not devices:
        raise DeviceError("RealSense: no device connected (open3d.t.io.RealSenseSensor.list_devices() finds none)")
    return devices


def sensor_config(serial: str, width: int, height: int, fps: int) -> dict[str, str]:
    """Open3D RealSenseSensorConfig map: RGB8 colour and Z16 depth at one resolution and rate."""
    resolution = f"{width},{height}"
    config = {"color_format": "RS2_FORMAT_RGB8", "depth_format": "RS2_FORMAT_Z16",
              "color_resolution": resolution, "depth_resolution": resolution, "fps": str(fps)}
    if serial:
        config["serial"] = serial
    return config


def metadata_intrinsics(meta) -> tuple[Intrinsics, float]:
    """(colour intrinsics, depth units per metre) of Open3D's RGBDVideoMetadata."""
    K = np.asarray(meta.intrinsics.intrinsic_matrix, dtype=np.float64)
    intr = Intrinsics(int(meta.width), int(meta.height), K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    return intr, float(meta.depth_scale)


class RealSenseCamera(Node):
    """Publishes aligned colour + depth from a RealSense camera (see the module docstring)."""

    OUTPUTS = {"rgb": Image, "depth": DepthImage, "rgbd/camera_info": CameraInfo}

    @dataclass(frozen=True)
    class Params:
        serial: str = param("", doc="serial number of the camera; empty = the first one")
        width: int = param(640, min=1, doc="colour and depth width [px]")
        height: int = param(480, min=1, doc="colour and depth height [px]")
        fps: int = param(30, min=1, max=300, doc="frame rate [Hz]")
        frame_id: str = param("rgbd", doc="frame_id of the images")
        buffer: int = param(2, min=1, max=100, doc="newest frames kept while the node is busy")
        timeout_s: float = param(5.0, min=0.1, doc="DeviceError after this long without a frame [s]")

    def setup(self) -> None:
        p = self.params
        realsense_devices()
        from open3d.t.io import RealSenseSensor, RealSenseSensorConfig

        self.sensor = RealSenseSensor()
        config = RealSenseSensorConfig(sensor_config(p.serial, p.width, p.height, p.fps))
        if not self.sensor.init_sensor(config, 0):
            raise DeviceError(f"RealSense {p.serial or '#0'}: cannot start {p.width}x{p.height} at {p.fps} Hz")
        self.sensor.start_capture()
        self.intrinsics, self.depth_scale = metadata_intrinsics(self.sensor.get_metadata())
        self.thread = FrameThread(self._frames(), "realsense", buffer=p.buffer, on_exit=self.sensor.stop_capture)
        self.timer = self.ctx.create_timer(0.002, self.poll, name="capture")

    def _frames(self):
        while True:
            rgbd = self.sensor.capture_frame(True, True)
            stamp = time.time_ns()
            color = np.ascontiguousarray(rgbd.color.as_tensor().numpy())
            depth = np.ascontiguousarray(rgbd.depth.as_tensor().numpy()).reshape(color.shape[:2])
            if color.size == 0:
                raise DeviceError(f"RealSense {self.params.serial or '#0'}: empty frame")
            yield stamp, (color, depth)

    def poll(self) -> None:
        """Publish queued frames; raise the capture thread's error or a timeout as DeviceError."""
        if self.thread.ident is None:  # capture starts with the graph (timers fire only after the start)
            self.last_frame = time.monotonic()
            self.thread.start()
        if drain(self.thread, self.publish):
            raise DeviceError(f"RealSense {self.params.serial or '#0'}: capture ended")
        if time.monotonic() - self.last_frame > self.params.timeout_s:
            raise DeviceError(f"RealSense {self.params.serial or '#0'}: no frame for {self.params.timeout_s} s")

    def publish(self, stamp_ns: int, frame) -> None:
        color, depth = frame
        self.last_frame = time.monotonic()
        fid = self.params.frame_id
        self.ctx.publish("rgbd/camera_info", camera_info(self.intrinsics, stamp_ns, fid))
        self.ctx.publish("rgb", Image(Header(stamp_ns, fid), color, "rgb8"))
        depth = depth.astype(np.uint16, copy=False)
        self.ctx.publish("depth", DepthImage(Header(stamp_ns, fid), depth, self.depth_scale))

    def close(self) -> None:
        if getattr(self, "thread", None) is not None:
            if self.thread.ident is None:
                self.thread.on_exit()  # never started: stop the sensor here
            self.thread.stop()
            if self.thread.ident is not None:
                self.thread.join(2.0)
