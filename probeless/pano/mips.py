"""Mipmaps of equirectangular frames and an emulation of GL trilinear texture lookups.

:func:`sample_equirect` reproduces what a fragment shader gets from ``textureLod`` on a texture
with ``GL_LINEAR_MIPMAP_LINEAR`` minification, ``GL_LINEAR`` magnification, ``GL_REPEAT`` in
``u`` (longitude) and ``GL_CLAMP_TO_EDGE`` in ``v``: bilinear within a level (texel centres at
half-integers), linear between the two levels around ``lod`` (``floor(lod)`` and the next one),
``lod`` clamped to ``[0, last level]``. Directions map to pixels by :mod:`probeless.pano.equirect`.
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.errors import ProbelessError
from probeless.pano.equirect import check_equirect, direction_to_pixel


def _halve(img: np.ndarray) -> np.ndarray:
    h, w, c = img.shape
    if h % 2 == 0 and w % 2 == 0:
        return img.reshape(h // 2, 2, w // 2, 2, c).mean(axis=(1, 3), dtype=np.float64).astype(np.float32)
    # odd height (GL leaves the filter of non-power-of-two sizes to the implementation): area
    # averaging to (2 floor(H/2), floor(H/2)) keeps every level 2:1 and every texel a true mean
    hh = h // 2
    out = cv2.resize(img, (2 * hh, hh), interpolation=cv2.INTER_AREA)
    return out.reshape(hh, 2 * hh, c).astype(np.float32)


def mip_levels(equirect: np.ndarray) -> list[np.ndarray]:
    """``[level0, level1, ...]`` of an (H, 2H, C) frame down to height 1, each level float32.

    Each level is the 2x2 box average of the previous one (what ``glGenerateMipmap`` does for
    power-of-two sizes); an odd height is area-averaged to ``floor(H / 2)`` (cv2.INTER_AREA).
    """
    img = check_equirect(equirect, "mip_levels")
    if img.shape[0] < 1 or img.shape[2] < 1:
        raise ProbelessError(f"mip_levels: empty image of shape {img.shape}")
    levels = [np.ascontiguousarray(img, dtype=np.float32)]
    while levels[-1].shape[0] > 1:
        levels.append(_halve(levels[-1]))
    return levels


def bilinear(img: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(M, C) float64 bilinear lookup of (M, 3) unit directions in one level: REPEAT u, CLAMP v."""
    h, w = img.shape[:2]
    u, v = direction_to_pixel(dirs, w, h)
    x, y = u - 0.5, v - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y1 = np.clip(y0.astype(np.int64) + 1, 0, h - 1)
    y0 = np.clip(y0.astype(np.int64), 0, h - 1)
    top = img[y0, x0] * (1.0 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1.0 - fx) + img[y1, x1] * fx
    return top * (1.0 - fy) + bottom * fy


def _check_levels(levels) -> list[np.ndarray]:
    if isinstance(levels, np.ndarray):
        levels = [levels]
    if not levels:
        raise ProbelessError("sample_equirect: no mip levels given")
    for i, lvl in enumerate(levels):
        check_equirect(lvl, f"sample_equirect: level {i}")
    return list(levels)


def sample_equirect(levels, dirs: np.ndarray, lod=0.0) -> np.ndarray:
    """(..., C) float32 trilinear lookup of directions ``dirs`` (..., 3) in the mip chain ``levels``.

    ``lod`` is a scalar or an array broadcastable to ``dirs.shape[:-1]``; it is clamped to
    ``[0, len(levels) - 1]``. Level ``l`` contributes with the hat weight ``max(0, 1 - |lod - l|)``,
    which is exactly GL's ``(1 - frac) * level[floor] + frac * level[floor + 1]``.
    """
    levels = _check_levels(levels)
    d = np.asarray(dirs, dtype=np.float64)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ProbelessError(f"sample_equirect: directions must be (..., 3), got shape {d.shape}")
    lead = d.shape[:-1]
    flat = d.reshape(-1, 3)
    try:
        lods = np.broadcast_to(np.asarray(lod, dtype=np.float64), lead).reshape(-1)
    except ValueError as exc:
        raise ProbelessError(f"sample_equirect: lod of shape {np.shape(lod)} does not fit directions "
                             f"{d.shape}") from exc
    lods = np.clip(lods, 0.0, len(levels) - 1)
    if not len(flat):
        return np.zeros((*lead, levels[0].shape[2]), dtype=np.float32)
    out = np.zeros((len(flat), levels[0].shape[2]), dtype=np.float64)
    for lvl in range(int(np.floor(lods.min())), int(np.ceil(lods.max())) + 1):
        wgt = np.maximum(0.0, 1.0 - np.abs(lods - lvl))
        sel = np.nonzero(wgt > 0.0)[0]
        if len(sel):
            out[sel] += wgt[sel, None] * bilinear(levels[lvl], flat[sel])
    return out.reshape(*lead, -1).astype(np.float32)
