"""Resampling a camera image into another camera model through a precomputed look-up table (LUT).

``build_lut(src, dst)`` evaluates, once, for every destination pixel centre the source pixel that
sees the same ray (dst.unproject -> src.project; OpenCV's map functions do it where they have both
models, :mod:`probeless.cameras.undistort_cv2`); ``remap`` then resamples each frame with
cv2.remap (black outside the source image or the model domains). ``undistort_direct`` is the
slow reference: it evaluates both models per pixel on every call and samples the same way.

The destination may also be a :class:`LongLat` equirectangular image in the source camera's frame:
longitude lon about the camera's -y axis (image "up"), lon = 0 on the optical axis (+z), lon > 0
towards +x (image right); latitude lat > 0 towards -y (up). A ray is
(cos lat sin lon, -sin lat, cos lat cos lon). Column j holds lon = (j + 0.5) / W * lon_span -
lon_span / 2, row i holds lat = lat_span / 2 - (i + 0.5) / H * lat_span, so the image centre
looks along the optical axis, up is up and right is right, as in the fisheye image.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from probeless.cameras.base import CameraModel, as_pixels, as_points, invalidate, normalize_rows, pixel_grid
from probeless.cameras.undistort_cv2 import OUTSIDE, opencv_lut

# OUTSIDE: map value of destination pixels with no source, far enough out for black with any kernel
INTERPOLATIONS = {"nearest": cv2.INTER_NEAREST, "linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC}


@dataclass(frozen=True)
class LongLat:
    """An equirectangular destination: ``width`` x ``height`` pixels spanning lon_span x lat_span degrees."""

    width: int
    height: int
    lon_span_deg: float = 360.0  # 360 = the full sphere; 180 = the hemisphere in front of the camera
    lat_span_deg: float = 180.0

    def unproject(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) pixels -> (N, 3) unit rays in the camera frame, all valid."""
        px = as_pixels(pixels)
        lon = np.radians((px[:, 0] + 0.5) / self.width * self.lon_span_deg - self.lon_span_deg / 2)
        lat = np.radians(self.lat_span_deg / 2 - (px[:, 1] + 0.5) / self.height * self.lat_span_deg)
        rays = np.column_stack([np.cos(lat) * np.sin(lon), -np.sin(lat), np.cos(lat) * np.cos(lon)])
        return rays, np.ones(len(px), bool)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) directions -> (N, 2) pixels and valid (inside the lon/lat spans)."""
        p = normalize_rows(as_points(points))
        lon = np.degrees(np.arctan2(p[:, 0], p[:, 2]))
        lat = np.degrees(np.arcsin(np.clip(-p[:, 1], -1, 1)))
        valid = (np.abs(lon) <= self.lon_span_deg / 2) & (np.abs(lat) <= self.lat_span_deg / 2)
        u = (lon + self.lon_span_deg / 2) / self.lon_span_deg * self.width - 0.5
        v = (self.lat_span_deg / 2 - lat) / self.lat_span_deg * self.height - 0.5
        return invalidate(np.column_stack([u, v]), valid), valid


Destination = CameraModel | LongLat


def sample_positions(src: CameraModel, dst: Destination) -> np.ndarray:
    """(H, W, 2) float64 source pixel (u, v) for every destination pixel centre; NaN where none."""
    rays, ok = dst.unproject(pixel_grid(dst.width, dst.height))
    uv, ok_src = src.project(np.where(ok[:, None], rays, 0.0))
    keep = ok & ok_src & src.in_image(uv)
    return invalidate(uv, keep).reshape(dst.height, dst.width, 2)


def maps_from_positions(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 2) positions -> cv2.remap (map_x, map_y) float32, OUTSIDE where NaN."""
    maps = np.where(np.isfinite(positions), positions, OUTSIDE).astype(np.float32)
    return np.ascontiguousarray(maps[..., 0]), np.ascontiguousarray(maps[..., 1])


def build_lut(src: CameraModel, dst: Destination, *, use_opencv: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The look-up table (map_x, map_y), float32 (H_dst, W_dst): where each destination pixel samples ``src``.

    Built by OpenCV where it has the same pair of models (:mod:`probeless.cameras.undistort_cv2`: Mei into
    an ideal omnidir xi = 1, pinhole or longlat destination; Kannala-Brandt and pinhole into an ideal
    pinhole), else (or with ``use_opencv=False``) from our own models; both give the same table within
    1e-3 px (tested).
    """
    table = opencv_lut(src, dst) if use_opencv else None
    return table if table is not None else maps_from_positions(sample_positions(src, dst))


def remap(image: np.ndarray, lut: tuple[np.ndarray, np.ndarray], interpolation: str = "linear") -> np.ndarray:
    """Resample ``image`` (H, W[, C]) through a LUT; black outside. Keeps rank and dtype.

    cv2.remap samples on a 1/32 px grid (its fixed-point interpolation tables): positions are exact
    to 1/64 px. (Here float32 maps remap faster than cv2.convertMaps' fixed-point form.)
    """
    flag = INTERPOLATIONS[interpolation]
    src = image.astype(np.float32) if image.dtype == np.float16 else image
    out = cv2.remap(src, lut[0], lut[1], flag, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    if image.ndim == 3 and out.ndim == 2:
        out = out[..., None]
    return out.astype(image.dtype, copy=False)


def undistort_direct(image: np.ndarray, src: CameraModel, dst: Destination,
                     interpolation: str = "linear") -> np.ndarray:
    """Reference: evaluate both models for every pixel on this call, then sample as :func:`remap` does."""
    return remap(image, maps_from_positions(sample_positions(src, dst)), interpolation)
