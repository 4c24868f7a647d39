"""Kannala-Brandt (equidistant) fisheye, as cv2.fisheye: r = theta_d(theta) in normalised units.

theta_d = theta * (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8), theta = the angle of
the ray from the optical axis; the distorted point is theta_d * (x, y) / |(x, y)|, then K.
Unlike cv2.fisheye (which uses atan(r) and so folds rays behind the camera forward), theta is
computed as atan2(|(x, y)|, z), so rays beyond 90 degrees project correctly. The domain is
theta < theta_max, the first angle (<= pi) where theta_d stops increasing.
"""

from __future__ import annotations

import numpy as np

from probeless.cameras.base import (
    CameraModel,
    apply_K,
    as_pixels,
    as_points,
    camera_matrix,
    header,
    invalidate,
    invert_K,
)
from probeless.errors import CalibrationError
from probeless.messages.sensor import CameraInfo


def theta_d(theta: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Distorted angle theta_d(theta) [rad]."""
    k = np.zeros(4)
    k[:len(D)] = D
    t2 = theta * theta
    return theta * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))


def theta_d_slope(theta: np.ndarray, D: np.ndarray) -> np.ndarray:
    """d theta_d / d theta."""
    k = np.zeros(4)
    k[:len(D)] = D
    t2 = theta * theta
    return 1 + t2 * (3 * k[0] + t2 * (5 * k[1] + t2 * (7 * k[2] + t2 * 9 * k[3])))


def monotonic_limit(D: np.ndarray, samples: int = 20001) -> float:
    """The largest theta in (0, pi] up to which theta_d is strictly increasing."""
    theta = np.linspace(0, np.pi, samples)
    bad = np.nonzero(theta_d_slope(theta, D) <= 0)[0]
    return float(np.pi if len(bad) == 0 else theta[max(bad[0] - 1, 1)])


def solve_theta(td: np.ndarray, D: np.ndarray, theta_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Invert theta_d on [0, theta_max] by Newton's method; returns (theta, converged)."""
    theta = np.clip(td, 0, theta_max)
    if len(D) == 0 or not np.any(D):
        return theta, td <= theta_max
    with np.errstate(all="ignore"):
        for _ in range(30):
            step = (theta_d(theta, D) - td) / theta_d_slope(theta, D)
            theta = np.clip(theta - step, 0, theta_max)
            if np.all(np.abs(step) < 1e-14):
                break
        ok = np.abs(theta_d(theta, D) - td) <= 1e-10
    return theta, ok


class KannalaBrandtModel(CameraModel):
    """Equidistant fisheye with polynomial distortion: K, D = (k1, k2, k3, k4) or empty."""

    model = "kannala_brandt"

    def __init__(self, width: int, height: int, K: np.ndarray, D: np.ndarray = ()):
        self.width, self.height = int(width), int(height)
        self.K = np.array(K, dtype=np.float64).reshape(3, 3)
        self.D = np.array(D, dtype=np.float64).ravel()
        if len(self.D) not in (0, 4):
            raise CalibrationError(f"kannala_brandt model needs D of 0 or 4 coefficients, got {len(self.D)}")
        self.theta_max = monotonic_limit(self.D)

    @classmethod
    def from_camera_info(cls, info: CameraInfo) -> KannalaBrandtModel:
        """The model of a ``kannala_brandt`` CameraInfo."""
        return cls(info.width, info.height, info.K, info.D)

    @classmethod
    def from_fov(cls, width: int, height: int, fov_deg: float) -> KannalaBrandtModel:
        """Ideal equidistant fisheye (r = f theta) whose ``fov_deg`` circle just fits the image.

        Principal point at the image centre; rays at fov_deg / 2 land on radius min(W, H) / 2.
        """
        theta = np.radians(fov_deg) / 2
        if not 0 < theta < np.pi:
            raise CalibrationError(f"kannala_brandt from_fov: fov_deg={fov_deg} must be in (0, 360)")
        f = (min(width, height) / 2) / theta
        return cls(width, height, camera_matrix(f, f, (width - 1) / 2, (height - 1) / 2))

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = as_points(points)
        rxy = np.hypot(p[:, 0], p[:, 1])
        theta = np.arctan2(rxy, p[:, 2])
        valid = (theta < self.theta_max) & ((rxy > 0) | (p[:, 2] > 0))
        with np.errstate(all="ignore"):
            scale = np.where(rxy > 0, theta_d(theta, self.D) / rxy, 0.0)
        uv = apply_K(self.K, p[:, :2] * scale[:, None])
        return invalidate(uv, valid), valid

    def unproject(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xy = invert_K(self.K, as_pixels(pixels))
        td = np.hypot(xy[:, 0], xy[:, 1])
        theta, valid = solve_theta(td, self.D, self.theta_max)
        with np.errstate(all="ignore"):
            s = np.where(td > 0, np.sin(theta) / td, 0.0)
        rays = np.column_stack([xy * s[:, None], np.cos(theta)])
        valid &= np.isfinite(rays).all(axis=1)
        return invalidate(rays, valid), valid

    def to_camera_info(self, frame_id: str = "", stamp_ns: int = 0) -> CameraInfo:
        return CameraInfo(header(frame_id, stamp_ns), self.width, self.height, "kannala_brandt", self.K.copy(),
                          self.D.copy())
