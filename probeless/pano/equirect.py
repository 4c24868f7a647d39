"""Equirectangular (latitude-longitude) panorama helpers: pixel <-> direction, texel solid angles.

Convention (used by every ``probeless.pano`` module, its shaders through ``probeless/gl/glsl/equirect.glsl``,
and every reader of real panoramas and photos):

* world ``z`` is up;
* row 0 is the top of the image (zenith side); pixel row ``r`` covers polar angles
  ``theta in [r, r + 1] * pi / H`` measured from ``+z``;
* column ``c`` covers longitudes ``phi in [c, c + 1] * 2 pi / W``, ``phi`` measured from ``+x``
  towards ``-y``: clockwise seen from above (column 0 starts at ``+x``, column ``W / 4`` at ``-y``,
  column ``W / 2`` at ``-x``, column ``3 W / 4`` at ``+y``);
* pixel centres sit at half-integer coordinates: direction of pixel ``(r, c)`` is
  ``(sin t cos p, -sin t sin p, cos t)`` with ``t = (r + 0.5) pi / H``, ``p = (c + 0.5) 2 pi / W``.

Why clockwise: a real 360° photo or video, like Blender's and Mitsuba's ``envmap`` lat-long maps, is laid out
so that turning right moves right in the image (for an upright viewer facing ``f``, right is ``f x z``; facing
``+x`` that is ``-y``). The counter-clockwise layout used before (``phi`` towards ``+y``) showed every real
panorama mirrored (issue 27); tests/pano/test_pano_orientation.py checks the layout against text drawn into a
panorama and against Mitsuba 3's ``envmap``.
"""

from __future__ import annotations

import numpy as np

from probeless.errors import ProbelessError


def _check_size(width: int, height: int) -> None:
    if int(width) < 1 or int(height) < 1:
        raise ProbelessError(f"equirect: size must be positive, got {width}x{height}")


def pixel_to_direction(u: np.ndarray, v: np.ndarray, width: int, height: int) -> np.ndarray:
    """(..., 3) unit directions of continuous pixel coordinates ``u`` (column) and ``v`` (row).

    Pixel centres are at ``u = c + 0.5``, ``v = r + 0.5``; ``v = 0`` is the zenith.
    """
    _check_size(width, height)
    theta = np.asarray(v, dtype=np.float64) * (np.pi / height)
    phi = np.asarray(u, dtype=np.float64) * (2.0 * np.pi / width)
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), -s * np.sin(phi), np.cos(theta)], axis=-1)


def direction_to_pixel(dirs: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Continuous pixel coordinates ``(u, v)`` of directions (..., 3) (normalised here); ``u`` in [0, W)."""
    _check_size(width, height)
    d = np.asarray(dirs, dtype=np.float64)
    n = np.linalg.norm(d, axis=-1)
    if np.any(n == 0):
        raise ProbelessError("equirect.direction_to_pixel: zero-length direction")
    theta = np.arccos(np.clip(d[..., 2] / n, -1.0, 1.0))
    phi = np.mod(np.arctan2(-d[..., 1], d[..., 0]), 2.0 * np.pi)  # clockwise seen from above (module doc)
    return phi * (width / (2.0 * np.pi)), theta * (height / np.pi)


def pixel_directions(width: int, height: int) -> np.ndarray:
    """(H, W, 3) float64 unit direction of every pixel centre."""
    _check_size(width, height)
    v, u = np.mgrid[0:height, 0:width] + 0.5
    return pixel_to_direction(u, v, width, height)


def row_solid_angles(width: int, height: int) -> np.ndarray:
    """(H,) float64 exact solid angle of one pixel in each row [sr]: ``2 pi / W (cos t0 - cos t1)``."""
    _check_size(width, height)
    edges = np.cos(np.linspace(0.0, np.pi, int(height) + 1))
    return (edges[:-1] - edges[1:]) * (2.0 * np.pi / width)


def solid_angles(width: int, height: int) -> np.ndarray:
    """(H, W) float64 exact solid angle of every pixel [sr]; sums to 4 pi."""
    return np.repeat(row_solid_angles(width, height)[:, None], int(width), axis=1)


def check_equirect(img: np.ndarray, what: str) -> np.ndarray:
    """``img`` as an (H, W, C) array with W == 2 H, else a ProbelessError naming ``what``."""
    a = np.asarray(img)
    if a.ndim != 3 or a.shape[1] != 2 * a.shape[0]:
        raise ProbelessError(f"{what}: expected an (H, 2H, C) equirectangular image, got shape {a.shape}")
    return a
