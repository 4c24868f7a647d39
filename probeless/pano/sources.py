"""Panorama readers: still equirectangular images (Radiance .hdr, EXR, PNG/JPG) and 360° video frames.

Pure readers, no node: :func:`default_panoramas` lists the shipped HDR panoramas (the default
input of every panorama evaluation); :func:`read_panorama` returns linear float32 RGB for HDR files
and sRGB uint8 for LDR ones; :class:`VideoFrames` decodes a video on a background thread into a small queue (the
paper's separate loader thread), so the consumer never waits for the decoder unless it wants to.
"""

from __future__ import annotations

import os
import queue
from typing import Iterator

import cv2
import numpy as np

from probeless.color import from_srgb8
from probeless.datasets.framethread import END, FrameThread
from probeless.errors import DatasetError
from probeless.paths import SHARED_DATA

HDR_SUFFIXES = (".hdr", ".pic", ".exr")
HDRI_DIR = SHARED_DATA / "hdri"  # the shipped true-HDR panoramas (../shared/data/hdri beside the checkout)
LDR_SUFFIXES = (".png", ".jpg", ".jpeg")


def default_panoramas() -> list[str]:
    """The ``*.hdr`` panoramas of :data:`HDRI_DIR`, sorted, as path strings; DatasetError if there are none."""
    paths = sorted(str(p) for p in HDRI_DIR.resolve().glob("*.hdr")) if HDRI_DIR.is_dir() else []
    if not paths:
        raise DatasetError(f"{HDRI_DIR.resolve()}: no .hdr panoramas found; pass --panorama FILE")
    return paths


def equirect_ok(shape: tuple[int, ...], path: str = "") -> None:
    """Raise DatasetError unless ``shape`` (H, W, ...) is an equirectangular 2:1 image (W == 2·H)."""
    if len(shape) < 2 or shape[0] < 1 or shape[1] != 2 * shape[0]:
        raise DatasetError(f"{path or 'panorama'}: shape {tuple(shape)} is not equirectangular "
                           f"(width must be 2 x height)")


def read_panorama(path: str, linear: bool = False) -> np.ndarray:
    """Read a panorama as RGB: .hdr/.pic/.exr -> float32 (H, W, 3) linear; .png/.jpg -> uint8 sRGB,
    or linear float32 in [0, 1] with ``linear``. DatasetError for a missing, unknown or unreadable file."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in HDR_SUFFIXES + LDR_SUFFIXES:
        raise DatasetError(f"{path}: unknown panorama type {suffix!r}, expected one of {HDR_SUFFIXES + LDR_SUFFIXES}")
    if not os.path.isfile(path):
        raise DatasetError(f"{path}: panorama file not found")
    hdr = suffix in HDR_SUFFIXES
    if suffix == ".exr":
        rgb = read_exr(path)
    else:
        img = cv2.imread(path, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR if hdr else cv2.IMREAD_COLOR)
        if img is None:
            raise DatasetError(f"{path}: cannot decode the image")
        rgb = np.ascontiguousarray(img[..., ::-1])
    if hdr:
        rgb = rgb.astype(np.float32, copy=False)
        if not np.isfinite(rgb).all():
            raise DatasetError(f"{path}: HDR panorama has non-finite pixels")
        return rgb
    if rgb.dtype != np.uint8:
        raise DatasetError(f"{path}: expected 8-bit pixels, got {rgb.dtype}")
    return from_srgb8(rgb) if linear else rgb


def read_exr(path: str) -> np.ndarray:
    """(H, W, 3) float32 RGB of an OpenEXR file (the ``OpenEXR`` package: this OpenCV build has no EXR codec).

    Channels ``RGB``/``RGBA`` (grouped by the reader), or ``R``, ``G``, ``B``, or a grey ``Y``; half floats
    are widened. DatasetError names the file for an unreadable file or other channels."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path)) as f:
            channels = {name: np.asarray(c.pixels) for name, c in f.channels().items()}
    except Exception as exc:  # OpenEXR raises plain exceptions for corrupt or non-EXR files
        raise DatasetError(f"{path}: cannot decode the OpenEXR image ({exc})") from None
    for name in ("RGB", "RGBA"):
        if name in channels and channels[name].ndim == 3:
            return np.ascontiguousarray(channels[name][..., :3], np.float32)
    if all(c in channels for c in "RGB"):
        return np.ascontiguousarray(np.stack([channels[c] for c in "RGB"], axis=-1), np.float32)
    if "Y" in channels:
        return np.ascontiguousarray(np.repeat(channels["Y"][..., None], 3, axis=-1), np.float32)
    raise DatasetError(f"{path}: OpenEXR channels {sorted(channels)}: expected RGB(A), R G B or Y")


def write_hdr_image(path, rgb: np.ndarray) -> None:
    """Write (H, W, 3) linear float RGB as Radiance ``.hdr``/``.pic`` (OpenCV, RGBE) or ``.exr`` (OpenEXR,
    float32, ZIP). DatasetError names the file when it cannot be written."""
    img = np.ascontiguousarray(np.asarray(rgb, np.float32))
    if img.ndim != 3 or img.shape[2] != 3 or not np.isfinite(img).all():
        raise DatasetError(f"{path}: expected finite (H, W, 3) RGB to write, got {img.dtype} {img.shape}")
    suffix = os.path.splitext(str(path))[1].lower()
    if suffix == ".exr":
        import OpenEXR

        try:
            with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                              {"RGB": img}) as f:
                f.write(str(path))
            return
        except Exception as exc:
            raise DatasetError(f"{path}: cannot write the OpenEXR image ({exc})") from None
    if suffix not in (".hdr", ".pic"):
        raise DatasetError(f"{path}: unknown HDR image type {suffix!r}, expected .hdr, .pic or .exr")
    if not cv2.imwrite(str(path), np.ascontiguousarray(img[..., ::-1])):
        raise DatasetError(f"{path}: cannot write the Radiance image")


def _decode(path: str, fps: float, loop: bool) -> Iterator[tuple[int, tuple[float, np.ndarray]]]:
    """(index, (t_s, rgb uint8)) for every frame; with ``loop`` reopens the file at the end (index 0 again)."""
    while True:
        cap = cv2.VideoCapture(path)
        i = 0
        try:
            while True:
                ok, bgr = cap.read()
                if not ok:
                    break
                yield i, (i / fps, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
                i += 1
        finally:
            cap.release()
        if i == 0:
            raise DatasetError(f"{path}: no frame could be decoded")
        if not loop:
            return


class VideoFrames:
    """Frames of a video file as ``(index, t_s, rgb uint8 (H, W, 3))``, decoded on a background thread.

    ``t_s = index / fps`` (constant frame rate; fps from the container unless given). With ``loop``
    the file is reopened at its end and indices start again at 0. ``buffer`` frames are decoded ahead.
    """

    def __init__(self, path: str, loop: bool = False, fps: float = 0.0, buffer: int = 4):
        if not os.path.isfile(path):
            raise DatasetError(f"{path}: video file not found")
        cap = cv2.VideoCapture(path)
        try:
            if not cap.isOpened():
                raise DatasetError(f"{path}: OpenCV cannot open the video")
            self.fps = fps or cap.get(cv2.CAP_PROP_FPS)
            self.frame_count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))  # container's estimate, may be off by one
            ok, first = cap.read()
        finally:
            cap.release()
        if not ok:
            raise DatasetError(f"{path}: cannot decode the first video frame")
        if not self.fps or not np.isfinite(self.fps) or self.fps <= 0:
            raise DatasetError(f"{path}: the container gives no frame rate; pass fps")
        self.path, self.loop, self.buffer = path, loop, buffer
        self.height, self.width = first.shape[:2]
        self.ended = False
        self.thread: FrameThread | None = None

    def start(self) -> "VideoFrames":
        """Start the decoding thread (idempotent)."""
        if self.thread is None:
            self.thread = FrameThread(_decode(self.path, self.fps, self.loop), f"video:{os.path.basename(self.path)}",
                                      wait=True, buffer=self.buffer)
            self.thread.start()
        return self

    def poll(self, timeout: float | None = 0.0) -> tuple[int, float, np.ndarray] | None:
        """The next frame, or None if none is decoded yet (or the stream ended: see ``ended``).
        ``timeout`` None waits as long as needed. Raises the decoder's error."""
        if self.ended:
            return None
        self.start()
        try:
            item = self.thread.queue.get(timeout=timeout) if timeout != 0 else self.thread.queue.get_nowait()
        except queue.Empty:
            return None
        if item is END:
            self.ended = True
            if self.thread.error is not None:
                raise self.thread.error
            return None
        index, (t_s, rgb) = item
        return index, t_s, rgb

    def __iter__(self) -> Iterator[tuple[int, float, np.ndarray]]:
        while (item := self.poll(timeout=None)) is not None:
            yield item

    def close(self) -> None:
        """Stop the decoding thread and release the file."""
        if self.thread is not None:
            self.thread.stop()
            self.thread.join(timeout=5.0)
            if not self.thread.is_alive():
                self.thread.frames.close()  # releases the capture of an unfinished pass

    def __enter__(self) -> "VideoFrames":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()
