"""OpenCV ``VideoCapture`` sources (device index, URL or file) as an iterator of stamped frames.

Stamps: live sources get the host wall clock ``time.time_ns()`` when ``grab()`` returns; files get
``t_open + CAP_PROP_POS_MSEC`` (the frame's presentation time in the container).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import cv2
import numpy as np

from probeless.errors import DeviceError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CaptureSettings:
    """Requested capture mode; 0 / None / "" = leave the device's default."""

    width: int = 0
    height: int = 0
    fps: float = 0.0
    exposure: float | None = None   # None = auto exposure; else the backend's CAP_PROP_EXPOSURE units
    fourcc: str = ""                # e.g. MJPG, YUYV


def parse_device(device: int | str) -> int | str:
    """A device index (int or digits) as int; a path or URL unchanged."""
    if isinstance(device, int):
        return device
    return int(device) if device.strip().isdigit() else device


def is_file(device: int | str) -> bool:
    """True when ``device`` names an existing file (played as a recording, with end of stream)."""
    return isinstance(device, str) and Path(device).is_file()


def open_capture(device: int | str, settings: CaptureSettings = CaptureSettings()) -> cv2.VideoCapture:
    """Open and configure ``device``; DeviceError naming it when it cannot be opened or set up."""
    dev = parse_device(device)
    cap = cv2.VideoCapture(dev)
    if not cap.isOpened():
        cap.release()
        raise DeviceError(f"camera {device!r}: cannot open (no such device, file or stream, or it is busy)")
    if is_file(dev):
        if settings != CaptureSettings():
            log.warning("camera %r is a file: width/height/fps/exposure/fourcc are ignored", device)
        return cap
    try:
        apply_settings(cap, device, settings)
    except DeviceError:
        cap.release()
        raise
    return cap


def apply_settings(cap: cv2.VideoCapture, device: int | str, s: CaptureSettings) -> None:
    """Set fourcc, size, fps and exposure; DeviceError when the size is not honoured, warnings otherwise."""
    if s.fourcc:
        if len(s.fourcc) != 4:
            raise DeviceError(f"camera {device!r}: fourcc {s.fourcc!r} must have 4 characters")
        _set(cap, device, cv2.CAP_PROP_FOURCC, cv2.VideoWriter_fourcc(*s.fourcc), "fourcc")
    if s.width:
        _set(cap, device, cv2.CAP_PROP_FRAME_WIDTH, s.width, "width")
    if s.height:
        _set(cap, device, cv2.CAP_PROP_FRAME_HEIGHT, s.height, "height")
    if s.fps:
        _set(cap, device, cv2.CAP_PROP_FPS, s.fps, "fps")
    # CAP_PROP_AUTO_EXPOSURE: V4L2 takes 1 = manual / 3 = auto; DirectShow & co. 0.25 / 0.75.
    v4l2 = cap.getBackendName() == "V4L2"
    if s.exposure is None:
        _set(cap, device, cv2.CAP_PROP_AUTO_EXPOSURE, 3 if v4l2 else 0.75, "auto exposure")
    else:
        _set(cap, device, cv2.CAP_PROP_AUTO_EXPOSURE, 1 if v4l2 else 0.25, "manual exposure")
        _set(cap, device, cv2.CAP_PROP_EXPOSURE, s.exposure, "exposure")
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    if (s.width and w != s.width) or (s.height and h != s.height):
        raise DeviceError(f"camera {device!r}: asked for {s.width or w}x{s.height or h}, the device gives {w}x{h}")


def _set(cap: cv2.VideoCapture, device, prop: int, value: float, what: str) -> None:
    if not cap.set(prop, value):
        log.warning("camera %r: the backend refused %s = %s", device, what, value)


def capture_frames(cap: cv2.VideoCapture, device: int | str, *, file: bool,
                   clock: Callable[[], int] = time.time_ns) -> Iterator[tuple[int, np.ndarray]]:
    """(stamp_ns, frame as OpenCV gives it) until a file ends; DeviceError when a live source fails a read."""
    t_open = clock()
    k = 0
    while True:
        if not cap.grab():
            if file:
                return
            raise DeviceError(f"camera {device!r}: stopped delivering frames (read failed after {k} frame(s))")
        stamp = t_open + round(cap.get(cv2.CAP_PROP_POS_MSEC) * 1e6) if file else clock()
        ok, frame = cap.retrieve()
        if not ok or frame is None:
            raise DeviceError(f"camera {device!r}: could not decode frame {k}")
        yield stamp, frame
        k += 1


def frame_image(frame: np.ndarray, where: str) -> tuple[np.ndarray, str]:
    """(HxWxC uint8, encoding rgb8 | mono8) of an OpenCV frame (BGR, BGRA or grey)."""
    if frame.dtype != np.uint8:
        raise DeviceError(f"{where}: {frame.dtype.name} frames are not supported, expected 8-bit")
    if frame.ndim == 2 or frame.shape[2] == 1:
        return np.ascontiguousarray(frame.reshape(frame.shape[0], frame.shape[1], 1)), "mono8"
    code = cv2.COLOR_BGRA2RGB if frame.shape[2] == 4 else cv2.COLOR_BGR2RGB
    return cv2.cvtColor(frame, code), "rgb8"

