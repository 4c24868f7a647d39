"""Fisheye footage on disk: an image folder or a video file, with stamps.

Stamps [ns]: from a stamps file (one stamp in seconds per line, one line per frame, strictly
increasing), else frame / fps, where fps defaults to the video's own rate or 30 Hz for a folder;
``time_offset_s`` is added to all. Images: grey files give mono8, colour files rgb8 (``color``
forces one); video frames are colour. Every frame must have the first frame's size.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from probeless.datasets.base import list_images, read_image
from probeless.datasets.textfiles import read_stamps_file
from probeless.errors import DatasetError

FOLDER_FPS = 30.0
COLORS = ("auto", "rgb8", "mono8")


@dataclass(frozen=True)
class FisheyeFootage:
    """Where the frames are and when they were taken."""

    path: Path
    kind: str                       # images | video
    images: tuple[Path, ...]        # image folder: the files in natural order
    stamps_ns: tuple[int, ...] | None  # per frame, or None = index / fps (a video whose length is unknown)
    fps: float
    offset_ns: int

    def stamp(self, k: int) -> int:
        """Stamp of frame ``k`` [ns]."""
        if self.stamps_ns is not None:
            return self.stamps_ns[k]
        return self.offset_ns + round(k * 1e9 / self.fps)


def open_fisheye(path: str | Path, *, stamps: str | None = None, fps: float = 0.0,
                 time_offset_s: float = 0.0) -> FisheyeFootage:
    """Describe the footage at ``path`` (folder or video); DatasetError naming what is wrong."""
    path = Path(path)
    offset = round(time_offset_s * 1e9)
    if path.is_dir():
        images = tuple(list_images(path))
        if not images:
            raise DatasetError(f"{path}: no image files in the folder")
        kind, rate, count = "images", fps or FOLDER_FPS, len(images)
    elif path.is_file():
        cap = cv2.VideoCapture(str(path))
        try:
            if not cap.isOpened():
                raise DatasetError(f"{path}: cannot open as a video (not an image folder either)")
            rate = fps or cap.get(cv2.CAP_PROP_FPS)
        finally:
            cap.release()
        if not rate or not np.isfinite(rate) or rate <= 0:
            raise DatasetError(f"{path}: the video has no frame rate; pass fps or stamps")
        kind, images, count = "video", (), None
    else:
        raise DatasetError(f"{path}: no such image folder or video file")
    stamp_list = None
    if stamps:
        stamp_list = read_stamps_file(Path(stamps))
        if count is not None and len(stamp_list) != count:
            raise DatasetError(f"{stamps}: {len(stamp_list)} stamp(s) but {path} has {count} image(s)")
        stamp_list = tuple(s + offset for s in stamp_list)
    return FisheyeFootage(path, kind, images, stamp_list, float(rate), offset)


def to_encoding(img: np.ndarray, color: str, where: str) -> tuple[np.ndarray, str]:
    """(HxWxC uint8, encoding) of an OpenCV image (BGR or grey) under the ``color`` choice."""
    if img.dtype != np.uint8:
        raise DatasetError(f"{where}: {img.dtype.name} image, expected 8-bit")
    grey = img.ndim == 2
    if color == "mono8" or (color == "auto" and grey):
        mono = img if grey else cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
        return np.ascontiguousarray(mono[:, :, None]), "mono8"
    if grey:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB), "rgb8"
    return cv2.cvtColor(img, cv2.COLOR_BGRA2RGB if img.shape[2] == 4 else cv2.COLOR_BGR2RGB), "rgb8"


def _raw_frames(footage: FisheyeFootage) -> Iterator[tuple[np.ndarray, str]]:
    if footage.kind == "images":
        for p in footage.images:
            yield read_image(p), str(p)
        return
    cap = cv2.VideoCapture(str(footage.path))
    try:
        k = 0
        while True:
            ok, frame = cap.read()
            if not ok:
                return
            yield frame, f"{footage.path} frame {k}"
            k += 1
    finally:
        cap.release()


def fisheye_frames(footage: FisheyeFootage, color: str = "auto") -> Iterator[tuple[int, np.ndarray, str]]:
    """(stamp_ns, HxWxC uint8, encoding) of every frame; DatasetError on a bad file or a count mismatch."""
    size = None
    k = -1
    for k, (img, where) in enumerate(_raw_frames(footage)):
        if footage.stamps_ns is not None and k >= len(footage.stamps_ns):
            raise DatasetError(f"{footage.path}: more frames than the {len(footage.stamps_ns)} stamps")
        if size is None:
            size = img.shape[:2]
        elif img.shape[:2] != size:
            raise DatasetError(f"{where}: {img.shape[1]}x{img.shape[0]}, the first frame is {size[1]}x{size[0]}")
        data, enc = to_encoding(img, color, where)
        yield footage.stamp(k), data, enc
    if footage.stamps_ns is not None and k + 1 != len(footage.stamps_ns):
        raise DatasetError(f"{footage.path}: {k + 1} frame(s) but {len(footage.stamps_ns)} stamps")


def first_frame_size(footage: FisheyeFootage) -> tuple[int, int]:
    """(width, height) of the first frame."""
    for img, _ in _raw_frames(footage):
        return img.shape[1], img.shape[0]
    raise DatasetError(f"{footage.path}: no frames")
