"""The camera model interface and small shared helpers (array checks, intrinsics, 2-D Newton solver).

Conventions shared by every model:

* camera frame = OpenCV optical frame: x right, y down, z forward (the optical axis);
* pixels are (u, v) = (column, row) with integer coordinates at pixel centres, so an image of
  width W covers u in [-0.5, W - 0.5];
* all model math is float64 and vectorised over N points.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo


class CameraModel(ABC):
    """A calibrated central camera: maps 3-D directions to pixels and back."""

    model: str = ""  # the CameraInfo.model name
    width: int
    height: int

    @abstractmethod
    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) camera-frame points -> (N, 2) float64 pixels (u, v) and (N,) bool valid.

        ``valid`` means the direction lies in the model's domain (not that it lands inside the image);
        pixels of invalid points are NaN.
        """

    @abstractmethod
    def unproject(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) pixels (u, v) -> (N, 3) float64 unit rays and (N,) bool valid (invalid rays are NaN)."""

    @abstractmethod
    def to_camera_info(self, frame_id: str = "", stamp_ns: int = 0) -> CameraInfo:
        """This calibration as a CameraInfo message."""

    def in_image(self, pixels: np.ndarray) -> np.ndarray:
        """(N,) bool: the pixel lies on the image area [-0.5, W - 0.5] x [-0.5, H - 0.5]."""
        px = as_pixels(pixels)
        with np.errstate(invalid="ignore"):
            return ((px[:, 0] >= -0.5) & (px[:, 0] <= self.width - 0.5)
                    & (px[:, 1] >= -0.5) & (px[:, 1] <= self.height - 0.5))

    def pixel_grid(self) -> np.ndarray:
        """(H * W, 2) float64 (u, v) of every pixel centre, row-major."""
        return pixel_grid(self.width, self.height)


def pixel_grid(width: int, height: int) -> np.ndarray:
    """(height * width, 2) float64 (u, v) of every pixel centre, row-major."""
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    return np.stack([u.ravel(), v.ravel()], axis=1)


def as_points(points: np.ndarray) -> np.ndarray:
    """``points`` as a float64 (N, 3) array; ValueError on another shape."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {p.shape}")
    return p


def as_pixels(pixels: np.ndarray) -> np.ndarray:
    """``pixels`` as a float64 (N, 2) array; ValueError on another shape."""
    p = np.asarray(pixels, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"pixels must have shape (N, 2), got {p.shape}")
    return p


def apply_K(K: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Normalised image coordinates (N, 2) -> pixels through the camera matrix K (skew K[0, 1] included)."""
    u = K[0, 0] * xy[:, 0] + K[0, 1] * xy[:, 1] + K[0, 2]
    v = K[1, 1] * xy[:, 1] + K[1, 2]
    return np.stack([u, v], axis=1)


def invert_K(K: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) -> normalised image coordinates; the inverse of :func:`apply_K`."""
    y = (uv[:, 1] - K[1, 2]) / K[1, 1]
    x = (uv[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return np.stack([x, y], axis=1)


def camera_matrix(fx: float, fy: float, cx: float, cy: float, skew: float = 0.0) -> np.ndarray:
    """3x3 float64 camera matrix [[fx, skew, cx], [0, fy, cy], [0, 0, 1]]."""
    return np.array([[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)


def normalize_rows(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` scaled to unit length (zero rows become NaN)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=1, keepdims=True)


def invalidate(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``values`` with the rows where ``valid`` is False set to NaN."""
    out = np.array(values, dtype=np.float64)
    out[~valid] = np.nan
    return out


def newton_2d(f: Callable[[np.ndarray], np.ndarray], target: np.ndarray, start: np.ndarray,
              iterations: int = 30, tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """Solve f(x) = target for (N, 2) x by Newton's method with a central-difference Jacobian.

    Returns (x, converged). Used to invert the radial-tangential distortion of the pinhole and
    omnidir models, which has no closed-form inverse.
    """
    x = np.array(start, dtype=np.float64)
    h = 1e-7
    dx = np.array([h, 0.0])
    dy = np.array([0.0, h])
    with np.errstate(all="ignore"):
        for _ in range(iterations):
            r = f(x) - target
            if np.all(np.abs(r) <= tol) or not np.any(np.isfinite(r)):
                break
            jx = (f(x + dx) - f(x - dx)) / (2 * h)
            jy = (f(x + dy) - f(x - dy)) / (2 * h)
            det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
            step_x = (jy[:, 1] * r[:, 0] - jy[:, 0] * r[:, 1]) / det
            step_y = (-jx[:, 1] * r[:, 0] + jx[:, 0] * r[:, 1]) / det
            x = x - np.stack([step_x, step_y], axis=1)
        res = np.abs(f(x) - target).max(axis=1)
    converged = np.isfinite(res) & (res <= 1e-9)
    return x, converged


def header(frame_id: str, stamp_ns: int) -> Header:
    """Header for a CameraInfo built by a model."""
    return Header(int(stamp_ns), frame_id)
