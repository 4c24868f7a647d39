"""CPU reference of the texturing projection (paper §4.3): atlas texels -> fisheye pixels -> colours.

The GPU texturer's fragment shader must agree with these two functions: a texel is *in view* when
the camera model accepts its direction, the direction is within ``fov_deg / 2`` of the optical
axis and the pixel lies on the image; its colour is the bilinear sample of the image there, pixel
centres at integer (u, v), edges replicated (GL ``CLAMP_TO_EDGE`` + ``LINEAR`` at
``(uv + 0.5) / size``, or ``cv2.remap`` with ``INTER_LINEAR`` and ``BORDER_REPLICATE``).

Everything works on per-component 1-D arrays inside: NumPy's small-axis reductions, (N, 3) @ (3, 3)
products and row fancy-indexing are many times slower than column arithmetic and ``np.take``,
and the brightness estimator runs this on millions of texels.
"""

from __future__ import annotations

import numpy as np

from probeless.cameras.base import CameraModel
from probeless.cameras.omnidir import OmnidirModel
from probeless.geom.rotation import invert_transform


def camera_columns(positions: np.ndarray, world_from_fisheye: np.ndarray) -> tuple[np.ndarray, ...]:
    """(x, y, z) float64 (N,) of world points (N, 3) in the fisheye's optical frame."""
    T = invert_transform(np.asarray(world_from_fisheye, np.float64))
    p = [np.asarray(positions)[:, k].astype(np.float64) for k in range(3)]
    return tuple(T[i, 0] * p[0] + T[i, 1] * p[1] + T[i, 2] * p[2] + T[i, 3] for i in range(3))


def _ideal_omnidir(model: CameraModel) -> bool:
    return isinstance(model, OmnidirModel) and len(model.D) == 0


def project_columns(positions: np.ndarray, model: CameraModel, world_from_fisheye: np.ndarray,
                    fov_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, in_view) (N,) each: :func:`project_texels` as separate columns."""
    x, y, z = camera_columns(positions, world_from_fisheye)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.sqrt(x * x + y * y + z * z)
        zs = z / r
        if _ideal_omnidir(model):  # the model's own formula (sphere_to_plane + apply_K), column-wise
            xi, K = model.xi, model.K
            denom = zs + xi
            valid = (denom > 0) & (1 + xi * zs > 0)
            mx, my = x / (r * denom), y / (r * denom)
            u = K[0, 0] * mx + K[0, 1] * my + K[0, 2]
            v = K[1, 1] * my + K[1, 2]
            valid &= np.isfinite(u) & np.isfinite(v)
            u[~valid], v[~valid] = np.nan, np.nan
        else:
            uv, valid = model.project(np.stack([x, y, z], axis=1))
            u, v = uv[:, 0], uv[:, 1]
        in_view = valid & (zs >= np.cos(np.radians(fov_deg) / 2))
        in_view &= (u >= -0.5) & (u <= model.width - 0.5) & (v >= -0.5) & (v <= model.height - 0.5)
    return u, v, in_view


def project_texels(positions: np.ndarray, model: CameraModel, world_from_fisheye: np.ndarray,
                   fov_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(uv (N, 2) float64 pixels, in_view (N,) bool) of world points seen by the fisheye.

    ``in_view``: the model projects the direction, its angle to the optical axis is at most
    ``fov_deg / 2`` and the pixel is on the image (``model.in_image``). ``uv`` is NaN where the
    model rejects the direction; it is finite (but off the image or field of view) elsewhere.
    """
    u, v, in_view = project_columns(positions, model, world_from_fisheye, fov_deg)
    return np.stack([u, v], axis=1), in_view


def sample_columns(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:func:`sample_image` at pixel columns ``u``, ``v`` (N,) -> (N, 3) float32 in 0..1."""
    img = np.ascontiguousarray(image)
    h, w = img.shape[:2]
    finite = np.isfinite(u) & np.isfinite(v)
    u, v = np.where(finite, u, 0.0), np.where(finite, v, 0.0)
    u0, v0 = np.floor(u).astype(np.intp), np.floor(v).astype(np.intp)
    fu, fv = (u - u0).astype(np.float32), (v - v0).astype(np.float32)
    c0, c1 = np.clip(u0, 0, w - 1), np.clip(u0 + 1, 0, w - 1)
    r0, r1 = np.clip(v0, 0, h - 1) * w, np.clip(v0 + 1, 0, h - 1) * w
    gu, gv = 1 - fu, 1 - fv
    weights = (gu * gv, fu * gv, gu * fv, fu * fv)
    corners = [3 * i for i in (r0 + c0, r0 + c1, r1 + c0, r1 + c1)]
    flat = img.reshape(-1)
    out = np.empty((len(u), 3), np.float32)
    for c in range(3):  # 1-D gathers per channel: (N, 3) x (N, 1) broadcasting is several times slower
        acc = np.zeros(len(u), np.float32)
        for i, weight in zip(corners, weights):
            acc += np.take(flat, i + c) * weight
        out[:, c] = acc * np.float32(1 / 255)
    out[~finite] = np.nan
    return out


def sample_image(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear samples (N, 3) float32 in 0..1 of a uint8 (h, w, 3) image at pixels ``uv`` (N, 2).

    Pixel centres are at integers; outside the image the border pixels are replicated. Rows with a
    non-finite ``uv`` come back NaN.
    """
    uv = np.asarray(uv, np.float64)
    return sample_columns(image, uv[:, 0], uv[:, 1])
