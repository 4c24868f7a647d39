"""Mei's unified sphere model (the "omnidir" runtime model), exactly as cv2.omnidir.

A direction X is put on the unit sphere, Xs = X / |X| = (xs, ys, zs), then projected from the
point (0, 0, -xi): m = (xs, ys) / (zs + xi), distorted with D = (k1, k2, p1, p2) (OpenCV's
radial-tangential formula) and mapped through K (skew K[0, 1] allowed).

Domain: zs + xi > 0 and 1 + xi * zs > 0 (the ray from the projection centre leaves the sphere at
Xs, the root Mei's lifting returns; this limits the field of view only when xi > 1).

Without distortion and with xi = 1, a ray at angle theta from the axis lands at radius
r = f sin(theta) / (1 + cos(theta)) = f tan(theta / 2) (stereographic), so any field of view
below 360 degrees is representable; the synthetic rig uses 185 degrees.
"""

from __future__ import annotations

import numpy as np

from probeless.cameras import pinhole
from probeless.cameras.base import (
    CameraModel,
    apply_K,
    as_pixels,
    as_points,
    camera_matrix,
    header,
    invalidate,
    invert_K,
    normalize_rows,
)
from probeless.errors import CalibrationError
from probeless.messages.sensor import CameraInfo


def sphere_to_plane(xs: np.ndarray, xi: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit-sphere points (N, 3) -> undistorted normalised plane points (N, 2) and valid."""
    denom = xs[:, 2] + xi
    valid = (denom > 0) & (1 + xi * xs[:, 2] > 0)
    with np.errstate(all="ignore"):
        m = xs[:, :2] / denom[:, None]
    return m, valid


def plane_to_sphere(m: np.ndarray, xi: float) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted normalised plane points (N, 2) -> unit-sphere points (N, 3) and valid (Mei's lifting)."""
    r2 = (m * m).sum(axis=1)
    disc = 1 + (1 - xi * xi) * r2
    valid = disc >= 0
    with np.errstate(all="ignore"):
        factor = (xi + np.sqrt(disc)) / (r2 + 1)
    xs = np.column_stack([factor * m[:, 0], factor * m[:, 1], factor - xi])
    return xs, valid


class OmnidirModel(CameraModel):
    """Unified sphere (Mei) camera: K, xi, D = (k1, k2, p1, p2) or empty."""

    model = "omnidir"

    def __init__(self, width: int, height: int, K: np.ndarray, xi: float, D: np.ndarray = ()):
        self.width, self.height = int(width), int(height)
        self.K = np.array(K, dtype=np.float64).reshape(3, 3)
        self.xi = float(xi)
        self.D = np.array(D, dtype=np.float64).ravel()
        if len(self.D) not in (0, 4) or not self.xi >= 0:
            raise CalibrationError(f"omnidir model needs D of 0 or 4 coefficients and xi >= 0, "
                                   f"got {len(self.D)} and {self.xi}")

    @classmethod
    def from_camera_info(cls, info: CameraInfo) -> OmnidirModel:
        """The model of an ``omnidir`` CameraInfo."""
        return cls(info.width, info.height, info.K, info.xi, info.D)

    @classmethod
    def from_fov(cls, width: int, height: int, fov_deg: float, xi: float = 1.0) -> OmnidirModel:
        """Ideal (distortion-free) omnidir camera whose ``fov_deg`` circle just fits the image.

        The principal point is the image centre ((W - 1) / 2, (H - 1) / 2); the circle of rays at
        fov_deg / 2 from the axis has radius min(W, H) / 2 pixels.
        """
        theta = np.radians(fov_deg) / 2
        if not (0 < theta < np.pi) or np.cos(theta) + xi <= 0 or 1 + xi * np.cos(theta) <= 0:
            raise CalibrationError(f"omnidir from_fov: fov_deg={fov_deg} is outside the domain of xi={xi}")
        f = (min(width, height) / 2) * (np.cos(theta) + xi) / np.sin(theta)
        return cls(width, height, camera_matrix(f, f, (width - 1) / 2, (height - 1) / 2), xi)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xs = normalize_rows(as_points(points))
        m, valid = sphere_to_plane(xs, self.xi)
        with np.errstate(all="ignore"):
            uv = apply_K(self.K, pinhole.distort(m, self.D))
        valid &= np.isfinite(uv).all(axis=1)
        return invalidate(uv, valid), valid

    def unproject(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m, valid = pinhole.undistort(invert_K(self.K, as_pixels(pixels)), self.D)
        xs, on_sphere = plane_to_sphere(m, self.xi)
        valid &= on_sphere
        return invalidate(normalize_rows(xs), valid), valid

    def to_camera_info(self, frame_id: str = "", stamp_ns: int = 0) -> CameraInfo:
        return CameraInfo(header(frame_id, stamp_ns), self.width, self.height, "omnidir", self.K.copy(),
                          self.D.copy(), xi=self.xi)
