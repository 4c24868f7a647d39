"""Undistortion tables built by OpenCV, where OpenCV has the same pair of models.

:func:`opencv_lut` answers the table :func:`probeless.cameras.undistort.build_lut` would build, or None
when OpenCV has no equivalent (then the caller evaluates our own models). OpenCV covers:

* Mei (``omnidir``) source -> ideal ``omnidir`` xi = 1 destination: ``cv2.omnidir.initUndistortRectifyMap``
  with RECTIFY_STEREOGRAPHIC (its xi = 1 projection is m = 2 x / (1 + z) with the centre ray along -y:
  hence halved focal lengths and the axis turn :data:`STEREO_R`);
* Mei source -> ideal pinhole destination: the same function with RECTIFY_PERSPECTIVE;
* Mei source -> longlat destination: the same function with RECTIFY_LONGLATI (:func:`longlat_matrix`);
* Kannala-Brandt source -> ideal pinhole: ``cv2.fisheye.initUndistortRectifyMap``;
* pinhole (plumb_bob, rational, thin-prism, tilted) source -> ideal pinhole: ``cv2.initUndistortRectifyMap``.

A source with skew, a destination with distortion or skew, an OCamCalib source, or a Kannala-Brandt or
pinhole source into a longlat or omnidir destination stays on our own path. Every table is then made to
mean exactly what ours means: positions off the source image ([-0.5, W - 0.5] x [-0.5, H - 0.5]) become
``OUTSIDE``. OpenCV does not know our model domains (e.g. a
Mei source with xi < 1 sees less than a hemisphere, a strongly distorted Kannala-Brandt lens stops at
``theta_max``), so the destination's border pixels are checked first: the rays of a destination image
reach their widest angle from the axis on its border, and when any border ray lies outside the source
model's domain the pair is left to our own path.

The rows are split into bands built on parallel threads (OpenCV's map functions are single-threaded and
release the GIL): the principal point of the destination matrix moves by the band's first row.
"""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from probeless.cameras.base import CameraModel
from probeless.cameras.kannala_brandt import KannalaBrandtModel
from probeless.cameras.omnidir import OmnidirModel
from probeless.cameras.pinhole import PinholeModel

OUTSIDE = -10.0  # as probeless.cameras.undistort.OUTSIDE (which imports it from here)
MIN_BAND_ROWS = 64
# our camera axes (x right, y down, z forward) from OpenCV's stereographic frame (centre ray -y, image y = +z)
STEREO_R = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# OpenCV's longlat frame from ours: x and y swapped (see longlat_matrix)
LONGLAT_R = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def longlat_matrix(dst) -> np.ndarray:
    """The destination matrix P of RECTIFY_LONGLATI for a :class:`~probeless.cameras.undistort.LongLat`.

    OpenCV's longlat ray is (-cos x, -sin x cos y, sin x sin y) with (x, y) = P^-1 (column, row, 1): x the
    angle from its -X axis, y the turn about X from -Y towards +Z. With our x and y axes swapped
    (:data:`LONGLAT_R`) x is the angle from "up" (our -y) and y the longitude + 90 degrees, so x comes from
    the row and y from the column, each through the pixel centre (+ 0.5)."""
    lat, lon = np.radians(dst.lat_span_deg), np.radians(dst.lon_span_deg)
    a, c = lat / dst.height, lon / dst.width
    p_inv = np.array([[0.0, a, np.pi / 2 - lat / 2 + a / 2], [c, 0.0, np.pi / 2 - lon / 2 + c / 2], [0.0, 0.0, 1.0]])
    return np.linalg.inv(p_inv)


def _ideal(model, cls) -> bool:
    return type(model) is cls and len(model.D) == 0 and model.K[0, 1] == 0


def _maker(src: CameraModel, dst):
    """(fn(P, (w, h), map_x, map_y): OpenCV's float32 table of a band whose destination matrix is P, written
    into map_x / map_y, and the destination's P); None when OpenCV has no equivalent of ``src`` -> ``dst``."""
    if getattr(src, "K", None) is None or src.K[0, 1] != 0:
        return None
    K = np.asarray(src.K, np.float64)
    if type(src) is OmnidirModel:
        D = np.zeros(4) if len(src.D) == 0 else np.asarray(src.D, np.float64)
        xi = np.array([src.xi])
        if _ideal(dst, OmnidirModel) and dst.xi == 1.0:
            P = np.array(dst.K, np.float64)
            P[0, 0] /= 2.0
            P[1, 1] /= 2.0
            return (lambda p, size, mx, my: cv2.omnidir.initUndistortRectifyMap(
                K, D.reshape(1, 4), xi, STEREO_R, p, size, cv2.CV_32FC1, cv2.omnidir.RECTIFY_STEREOGRAPHIC,
                map1=mx, map2=my)), P
        if _ideal(dst, PinholeModel):
            return (lambda p, size, mx, my: cv2.omnidir.initUndistortRectifyMap(
                K, D.reshape(1, 4), xi, np.eye(3), p, size, cv2.CV_32FC1, cv2.omnidir.RECTIFY_PERSPECTIVE,
                map1=mx, map2=my)), \
                np.array(dst.K, np.float64)
        if hasattr(dst, "lon_span_deg"):  # a LongLat destination (probeless.cameras.undistort)
            return (lambda p, size, mx, my: cv2.omnidir.initUndistortRectifyMap(
                K, D.reshape(1, 4), xi, LONGLAT_R, p, size, cv2.CV_32FC1, cv2.omnidir.RECTIFY_LONGLATI,
                map1=mx, map2=my)), longlat_matrix(dst)
        return None
    if not _ideal(dst, PinholeModel):
        return None
    if type(src) is KannalaBrandtModel:
        D = np.zeros(4)
        D[:len(src.D)] = src.D
        return (lambda p, size, mx, my: cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), p, size, cv2.CV_32FC1,
                                                                             map1=mx, map2=my)), \
            np.array(dst.K, np.float64)
    if type(src) is PinholeModel:
        D = np.asarray(src.D, np.float64) if len(src.D) else np.zeros(5)
        if len(D) not in (4, 5, 8, 12, 14):
            return None
        return (lambda p, size, mx, my: cv2.initUndistortRectifyMap(K, D, None, p, size, cv2.CV_32FC1,
                                                                    map1=mx, map2=my)), \
            np.array(dst.K, np.float64)
    return None


def border_in_domain(src: CameraModel, dst) -> bool:
    """True when every border pixel of ``dst`` sees a ray inside ``src``'s model domain (module doc)."""
    u, v = np.arange(dst.width, dtype=np.float64), np.arange(dst.height, dtype=np.float64)
    top, left = np.zeros_like(u), np.zeros_like(v)
    border = np.concatenate([np.column_stack([u, top]), np.column_stack([u, top + dst.height - 1]),
                             np.column_stack([left, v]), np.column_stack([left + dst.width - 1, v])])
    rays, ok = dst.unproject(border)
    if not ok.all():
        return False
    _, ok_src = src.project(rays)
    return bool(ok_src.all())


def _band(make, P: np.ndarray, out: tuple[np.ndarray, np.ndarray], rows: tuple[int, int],
          src_size: tuple[int, int]) -> None:
    """Rows ``rows`` of the table into ``out``, then positions off the source image set to OUTSIDE."""
    r0, r1 = rows
    p = P.copy()
    p[1, 2] -= r0
    mx, my = out[0][r0:r1], out[1][r0:r1]
    got = make(p, (mx.shape[1], r1 - r0), mx, my)
    if got[0] is not mx and not np.shares_memory(got[0], mx):  # not written in place (never seen; kept safe)
        mx[...], my[...] = got
    w, h = src_size
    off = ~((mx >= -0.5) & (mx <= w - 0.5) & (my >= -0.5) & (my <= h - 0.5))  # NaN is off too
    if off.any():
        mx[off] = OUTSIDE
        my[off] = OUTSIDE


def opencv_lut(src: CameraModel, dst, threads: int | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """OpenCV's table for ``src`` -> ``dst`` with our conventions (module doc), or None where OpenCV has no
    equivalent. ``threads``: parallel row bands (None: the CPU count)."""
    found = _maker(src, dst)
    if found is None or not border_in_domain(src, dst):
        return None
    make, P = found
    n = max(1, min(threads or os.cpu_count() or 1, dst.height // MIN_BAND_ROWS))
    edges = np.linspace(0, dst.height, n + 1).round().astype(int)
    bands = list(zip(edges[:-1], edges[1:]))
    out = (np.empty((dst.height, dst.width), np.float32), np.empty((dst.height, dst.width), np.float32))
    size = (src.width, src.height)
    if n == 1:
        _band(make, P, out, bands[0], size)
    else:
        list(_pool(n).map(lambda rows: _band(make, P, out, rows, size), bands))
    return out


@functools.lru_cache(maxsize=4)
def _pool(n: int) -> ThreadPoolExecutor:
    """A lasting pool of ``n`` threads (no thread start per table)."""
    return ThreadPoolExecutor(n, thread_name_prefix="undistort-lut")
