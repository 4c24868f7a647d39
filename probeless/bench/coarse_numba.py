"""The brightness Δ as a compiled serial loop (numba ``@njit``): the reference ``probeless bench coarse``
times the vectorised :func:`probeless.coarse.brightness.estimate_delta` against.

It is the paper's per-texel loop (:func:`~probeless.coarse.brightness.estimate_delta_serial`) as a
competent engineer would write it for speed: one compiled pass over the same texels, no temporaries.
Per texel: observed? old value usable? world -> fisheye transform, field of view, unified-sphere
projection (ideal omnidir, the texturer's runtime model), image bounds, even-odd point-in-visibility-
polygon, bilinear sample, new value usable? accumulate. Same inputs, same result (checked by the bench
and the tests to float32 round-off).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from probeless.coarse.brightness import DARK, OFFSET_M, SATURATED
from probeless.coarse.visibility import is_convex, visibility_polygon
from probeless.errors import SchemaError
from probeless.geom.rotation import invert_transform


@njit(cache=True, nogil=True)
def _poly_contains(poly, x, y):  # pragma: no cover - compiled
    inside = False
    n = poly.shape[0]
    xj, yj = poly[n - 1, 0], poly[n - 1, 1]
    for i in range(n):
        xi, yi = poly[i, 0], poly[i, 1]
        if (yi > y) != (yj > y) and x < (xj - xi) * (y - yi) / (yj - yi) + xi:
            inside = not inside
        xj, yj = xi, yi
    return inside


@njit(cache=True, nogil=True)
def _delta_loop(index, position, normal, atlas, scale, observed, image, T, cam, poly, use_poly,
                dark, saturated, offset_m):  # pragma: no cover - compiled
    fx, skew, cx, fy, cy, xi, cos_half = cam[0], cam[1], cam[2], cam[3], cam[4], cam[5], cam[6]
    h, w, aw = image.shape[0], image.shape[1], atlas.shape[1]
    total = np.zeros(3)
    n = 0
    for k in range(index.shape[0]):
        ar, ac = index[k] // aw, index[k] % aw
        if not observed[ar, ac]:
            continue
        o0, o1, o2 = atlas[ar, ac, 0] * scale, atlas[ar, ac, 1] * scale, atlas[ar, ac, 2] * scale
        top = max(o0, max(o1, o2))
        if not (top < saturated and top > dark):
            continue
        px, py, pz = position[k, 0], position[k, 1], position[k, 2]
        x = T[0, 0] * px + T[0, 1] * py + T[0, 2] * pz + T[0, 3]
        y = T[1, 0] * px + T[1, 1] * py + T[1, 2] * pz + T[1, 3]
        z = T[2, 0] * px + T[2, 1] * py + T[2, 2] * pz + T[2, 3]
        r = math.sqrt(x * x + y * y + z * z)
        if r == 0.0 or z / r < cos_half:
            continue
        zs = z / r
        if zs + xi <= 0.0 or 1.0 + xi * zs <= 0.0:
            continue
        mx, my = x / r / (zs + xi), y / r / (zs + xi)
        u, v = fx * mx + skew * my + cx, fy * my + cy
        if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5):
            continue
        if use_poly and not _poly_contains(poly, px + offset_m * normal[k, 0], py + offset_m * normal[k, 1]):
            continue
        u0, v0 = math.floor(u), math.floor(v)
        fu, fv = u - u0, v - v0
        c0, c1 = min(max(int(u0), 0), w - 1), min(max(int(u0) + 1, 0), w - 1)
        r0, r1 = min(max(int(v0), 0), h - 1), min(max(int(v0) + 1, 0), h - 1)
        new = np.empty(3)
        for c in range(3):
            new[c] = ((image[r0, c0, c] * (1 - fu) + image[r0, c1, c] * fu) * (1 - fv)
                      + (image[r1, c0, c] * (1 - fu) + image[r1, c1, c] * fu) * fv) / 255.0
        top = max(new[0], max(new[1], new[2]))
        if not (top < saturated and top > dark):
            continue
        total[0] += new[0] - o0
        total[1] += new[1] - o1
        total[2] += new[2] - o2
        n += 1
    return total, n


def estimate_delta_numba(atlas_rgb: np.ndarray, observed: np.ndarray, texmap, image: np.ndarray, model,
                         world_from_fisheye: np.ndarray, fov_deg: float, floorplan: np.ndarray, *, sample_idx,
                         dark: float = DARK, saturated: float = SATURATED,
                         offset_m: float = OFFSET_M) -> tuple[np.ndarray, int]:
    """(Δ (3,) float32, texels used): :func:`~probeless.coarse.brightness.estimate_delta`'s arguments and
    result, computed by the compiled serial loop; ``sample_idx`` a ``BrightnessSample``. The fisheye
    ``model`` must be the runtime ideal omnidir (D = 0): SchemaError otherwise. The atlas may be a strided
    view (e.g. the RGB of an RGBA atlas): the loop reads it in place, as the vectorised estimate does."""
    if len(getattr(model, "D", (0,))) or not hasattr(model, "xi"):
        raise SchemaError(f"estimate_delta_numba: needs an ideal omnidir model (D = 0), got {type(model).__name__}")
    wff = np.asarray(world_from_fisheye, np.float64)
    T = np.ascontiguousarray(invert_transform(wff))
    K = np.asarray(model.K, np.float64)
    cam = np.array([K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2], float(model.xi),
                    math.cos(math.radians(fov_deg) / 2)])
    use_poly = not is_convex(floorplan)
    poly = (np.ascontiguousarray(visibility_polygon(np.asarray(floorplan, np.float64), wff[:2, 3]), np.float64)
            if use_poly else np.zeros((1, 2)))
    s = sample_idx
    scale = 1 / 255.0 if atlas_rgb.dtype == np.uint8 else 1.0
    total, n = _delta_loop(s.index, np.asarray(s.position, np.float64), np.asarray(s.normal, np.float64),
                           atlas_rgb, scale, observed, np.ascontiguousarray(image),
                           T, cam, poly, use_poly, float(dark), float(saturated), float(offset_m))
    if n == 0:
        return np.zeros(3, np.float32), 0
    return (total / n).astype(np.float32), int(n)
