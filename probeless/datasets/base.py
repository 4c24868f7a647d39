"""The common record of an RGB-D sequence on disk, and the image/pose helpers every reader shares.

A reader (tum, redwood, sevenscenes) turns a folder into an :class:`RgbdSequence`: frames with
stamps, file paths and an optional ``world_from_camera`` pose, plus pinhole intrinsics and the
depth scale. Images are decoded only when read (:func:`read_color`, :func:`read_depth`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from probeless.errors import DatasetError
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
ORTHONORMAL_TOLERANCE = 1e-2  # a rotation further than this from orthonormal is an error, not noise


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of the colour/depth images [px]."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> np.ndarray:
        """3x3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class RgbdFrame:
    """One colour/depth pair. ``pose`` is world_from_camera (4x4 float64) or None."""

    index: int              # position in the folder's own numbering (7-Scenes frame number, list order)
    stamp_ns: int           # colour capture time [ns]
    depth_stamp_ns: int     # depth capture time [ns] (= stamp_ns where the format has no separate stamps)
    rgb_path: Path
    depth_path: Path
    pose: np.ndarray | None = None


@dataclass(frozen=True)
class RgbdSequence:
    """A whole RGB-D folder: frames in time order, intrinsics, depth scale and where each came from."""

    format: str                     # tum | redwood | 7scenes
    root: Path
    frames: tuple[RgbdFrame, ...]
    intrinsics: Intrinsics
    intrinsics_source: str          # file the intrinsics were read from, or why a default applies
    depth_scale: float              # depth units per metre
    rate_hz: float                  # nominal frame rate (fps for formats without stamps, else median)
    pose_source: str | None = None  # file the poses were read from; None = no poses
    notes: tuple[str, ...] = ()     # e.g. frames dropped by the association
    depth_invalid: int | None = None  # stored value meaning "no measurement", read as 0 (7-Scenes: 65535)

    @property
    def has_poses(self) -> bool:
        return any(f.pose is not None for f in self.frames)


def natural_key(path: Path) -> tuple:
    """Sort key ordering ``2.png`` before ``10.png``."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name))


def list_images(folder: Path) -> list[Path]:
    """Image files of ``folder`` in natural order."""
    return sorted((p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()), key=natural_key)


def read_color(path: Path) -> np.ndarray:
    """RGB uint8 HxWx3 of a colour image (grey images are expanded); DatasetError naming the file."""
    img = read_image(path)
    if img.dtype != np.uint8:
        raise DatasetError(f"{path}: colour image is {img.dtype.name}, expected 8-bit")
    if img.ndim == 2:
        return np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))
    code = cv2.COLOR_BGRA2RGB if img.shape[2] == 4 else cv2.COLOR_BGR2RGB
    return cv2.cvtColor(img, code)


def read_depth(path: Path, invalid: int | None = None) -> np.ndarray:
    """uint16 HxW depth as stored, pixels equal to ``invalid`` set to 0 (0 = invalid); DatasetError naming the file."""
    img = read_image(path)
    if img.dtype != np.uint16 or img.ndim != 2:
        raise DatasetError(f"{path}: depth image is {img.dtype.name} with shape {img.shape}, expected uint16 HxW")
    if invalid is not None:
        img[img == invalid] = 0
    return img


def read_image(path: Path) -> np.ndarray:
    """An image file as OpenCV reads it unchanged (BGR order); DatasetError naming a missing/corrupt file."""
    if not Path(path).is_file():
        raise DatasetError(f"{path}: image file is missing")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise DatasetError(f"{path}: cannot decode image (corrupt or unsupported format)")
    return img


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) of an image file."""
    img = read_image(path)
    return img.shape[1], img.shape[0]


def orthonormalize(T: np.ndarray, where: str) -> np.ndarray:
    """Rigid 4x4 with the rotation projected on SO(3) by SVD; DatasetError for NaN or a non-rotation."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise DatasetError(f"{where}: invalid pose (NaN, inf or not 4x4)")
    if np.max(np.abs(T[3] - (0.0, 0.0, 0.0, 1.0))) > 1e-6:
        raise DatasetError(f"{where}: invalid pose, last row {T[3].tolist()} is not [0, 0, 0, 1]")
    R = T[:3, :3]
    if np.max(np.abs(R.T @ R - np.eye(3))) > ORTHONORMAL_TOLERANCE or np.linalg.det(R) <= 0:
        raise DatasetError(f"{where}: invalid pose, rotation is not close to orthonormal with det +1")
    U, _, Vt = np.linalg.svd(R)
    out = np.eye(4)
    out[:3, :3] = U @ Vt
    out[:3, 3] = T[:3, 3]
    return out


def camera_info(intr: Intrinsics, stamp_ns: int, frame_id: str) -> CameraInfo:
    """Distortion-free pinhole CameraInfo of ``intr``."""
    return CameraInfo(Header(stamp_ns, frame_id), intr.width, intr.height, "pinhole", intr.K)


def check_intrinsics(intr: Intrinsics, first_rgb: Path) -> None:
    """DatasetError unless the first colour image has the intrinsics' size."""
    w, h = image_size(first_rgb)
    if (w, h) != (intr.width, intr.height):
        raise DatasetError(f"{first_rgb}: image is {w}x{h} but the intrinsics are for {intr.width}x{intr.height}")


def median_rate(stamps_ns: list[int]) -> float:
    """Frame rate [Hz] from the median stamp interval (0.0 for fewer than two stamps)."""
    if len(stamps_ns) < 2:
        return 0.0
    dt = float(np.median(np.diff(np.asarray(stamps_ns, dtype=np.int64))))
    return 1e9 / dt if dt > 0 else 0.0
