"""Pinhole camera with OpenCV distortion, exactly as cv2.projectPoints / cv2.undistortPoints.

D = (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tau_x, tau_y]]]]): rational radial,
tangential, thin-prism and tilted-sensor terms. The radial-tangential part is shared with the
omnidir (Mei) model, whose D = (k1, k2, p1, p2) is the same formula. One difference: a skew
K[0, 1] is applied here (as cv2.omnidir and cv2.fisheye do), while cv2.projectPoints ignores it.
"""

from __future__ import annotations

import numpy as np

from probeless.cameras.base import (
    CameraModel,
    apply_K,
    as_pixels,
    as_points,
    header,
    invalidate,
    invert_K,
    newton_2d,
    normalize_rows,
)
from probeless.messages.sensor import CameraInfo


def full_coefficients(D: np.ndarray) -> np.ndarray:
    """D zero-padded to OpenCV's 14 coefficients."""
    out = np.zeros(14)
    out[:len(D)] = D
    return out


def tilt_matrix(tau_x: float, tau_y: float) -> np.ndarray:
    """OpenCV's tilted-sensor projection matrix (computeTiltProjectionMatrix)."""
    cx, sx, cy, sy = np.cos(tau_x), np.sin(tau_x), np.cos(tau_y), np.sin(tau_y)
    rot_x = np.array([[1, 0, 0], [0, cx, sx], [0, -sx, cx]])
    rot_y = np.array([[cy, 0, -sy], [0, 1, 0], [sy, 0, cy]])
    rot = rot_y @ rot_x
    proj_z = np.array([[rot[2, 2], 0, -rot[0, 2]], [0, rot[2, 2], -rot[1, 2]], [0, 0, 1]])
    return proj_z @ rot


def distort(xy: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Undistorted normalised coordinates (N, 2) -> distorted ones, OpenCV's model for any len(D)."""
    if len(D) == 0:
        return xy
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tx, ty = full_coefficients(D)
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + r2 * (s1 + s2 * r2)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + r2 * (s3 + s4 * r2)
    if tx != 0 or ty != 0:
        t = tilt_matrix(tx, ty)
        hx = t[0, 0] * xd + t[0, 1] * yd + t[0, 2]
        hy = t[1, 0] * xd + t[1, 1] * yd + t[1, 2]
        hz = t[2, 0] * xd + t[2, 1] * yd + t[2, 2]
        xd, yd = hx / hz, hy / hz
    return np.stack([xd, yd], axis=1)


def undistort(xy_d: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distorted normalised coordinates -> undistorted ones (Newton on :func:`distort`), and converged."""
    if len(D) == 0:
        return xy_d, np.isfinite(xy_d).all(axis=1)
    return newton_2d(lambda p: distort(p, D), xy_d, xy_d)


class PinholeModel(CameraModel):
    """Perspective camera: K and OpenCV distortion D (see module docstring)."""

    model = "pinhole"

    def __init__(self, width: int, height: int, K: np.ndarray, D: np.ndarray = ()):
        self.width, self.height = int(width), int(height)
        self.K = np.array(K, dtype=np.float64).reshape(3, 3)
        self.D = np.array(D, dtype=np.float64).ravel()

    @classmethod
    def from_camera_info(cls, info: CameraInfo) -> PinholeModel:
        """The model of a ``pinhole`` CameraInfo."""
        return cls(info.width, info.height, info.K, info.D)

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float) -> PinholeModel:
        """Distortion-free pinhole with horizontal field of view ``hfov_deg``, principal point at the centre."""
        f = (width / 2) / np.tan(np.radians(hfov_deg) / 2)
        K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]])
        return cls(width, height, K)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = as_points(points)
        valid = p[:, 2] > 0
        with np.errstate(all="ignore"):
            xy = p[:, :2] / p[:, 2:3]
            uv = apply_K(self.K, distort(xy, self.D))
        valid &= np.isfinite(uv).all(axis=1)
        return invalidate(uv, valid), valid

    def unproject(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xy, valid = undistort(invert_K(self.K, as_pixels(pixels)), self.D)
        rays = normalize_rows(np.column_stack([xy, np.ones(len(xy))]))
        return invalidate(rays, valid), valid

    def to_camera_info(self, frame_id: str = "", stamp_ns: int = 0) -> CameraInfo:
        return CameraInfo(header(frame_id, stamp_ns), self.width, self.height, "pinhole", self.K.copy(), self.D.copy())
