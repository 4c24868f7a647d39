"""Texture maps of :class:`~probeless.ibl.materials.Principled` materials: reading and CPU sampling.

Maps are numpy arrays with row 0 the top of the image. Texture coordinates follow the OBJ convention: u grows to
the right, v grows *upwards* (v = 0 is the bottom row), and both wrap (repeat). A GL texture uploaded row 0 first
must be sampled at ``(u, 1 - v)`` to agree with :func:`sample_map`.
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.color import from_srgb8, srgb_to_linear
from probeless.errors import PbgiError
from probeless.ibl.materials import Principled


def load_material_maps(material: Principled) -> dict[str, np.ndarray]:
    """The maps a :class:`Principled` names, read from disk: ``{"base_color_map": (H, W, 3) float32 linear RGB,
    "roughness_map": (H, W) float32, "metalness_map": (H, W) float32}``, only the keys whose file is set.

    Base colour: 8- and 16-bit files are sRGB-decoded, float files (EXR, HDR) are taken as linear; a grey file gives
    equal channels. Roughness, metalness: linear, scaled to 0..1 (8/16 bit), first channel (red) of a colour file.
    Alpha channels are dropped.
    """
    out = {}
    if material.base_color_map:
        img = _read(material.base_color_map, "base_color_map")
        rgb = np.repeat(img[..., None], 3, axis=-1) if img.ndim == 2 else img[..., 2::-1]  # BGR(A) -> RGB
        if rgb.dtype == np.uint8:
            linear = from_srgb8(rgb)
        elif np.issubdtype(rgb.dtype, np.floating):
            linear = rgb
        else:
            linear = srgb_to_linear(_unit_range(rgb))
        out["base_color_map"] = np.ascontiguousarray(linear, np.float32)
    for key in ("roughness_map", "metalness_map"):
        path = getattr(material, key)
        if path:
            img = _read(path, key)
            channel = img if img.ndim == 2 else img[..., 2]  # OpenCV's channel 2 is red
            out[key] = np.clip(_unit_range(channel), 0.0, 1.0).astype(np.float32)
    return out


def _read(path: str, key: str) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH)
    if img is None:
        raise PbgiError(f"principled.{key}: cannot read image {path}")
    return img


def _unit_range(img: np.ndarray) -> np.ndarray:
    """Integer codes scaled to 0..1 by their type's maximum (uint8: 255, uint16: 65535); floats kept."""
    if np.issubdtype(img.dtype, np.integer):
        return img.astype(np.float64) / np.iinfo(img.dtype).max
    return img.astype(np.float64)


def sample_map(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear, wrapping lookup of ``image`` (H, W) or (H, W, C) at texture coordinates ``uv`` (..., 2) (module doc).

    Texel (row r, column c) has its centre at ``u = (c + 0.5) / W``, ``v = 1 - (r + 0.5) / H``. Returns (...) or
    (..., C) float64.
    """
    img = np.asarray(image, np.float64)
    uv = np.asarray(uv, np.float64)
    h, w = img.shape[:2]
    x = uv[..., 0] * w - 0.5
    y = (1.0 - uv[..., 1]) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    c0, r0 = x0.astype(np.int64) % w, y0.astype(np.int64) % h
    c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    if img.ndim == 3:
        fx, fy = fx[..., None], fy[..., None]
    top = img[r0, c0] * (1 - fx) + img[r0, c1] * fx
    bottom = img[r1, c0] * (1 - fx) + img[r1, c1] * fx
    return top * (1 - fy) + bottom * fy
