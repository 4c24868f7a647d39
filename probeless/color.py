"""The sRGB transfer function (IEC 61966-2-1) and Rec.709 luminance, one copy for the whole project.

Names say the direction: ``srgb_to_linear`` / ``linear_to_srgb`` map floats to floats,
``from_srgb8`` decodes 8-bit sRGB codes to linear floats, ``to_srgb8`` encodes linear floats to
8-bit sRGB codes. :func:`quantize8` turns values that are already encoded (0..1) into codes, with no
curve. Linear values are scene- or camera-referred with 1.0 = white; sRGB-encoded floats are 0..1.
(GLSL copies of the curve stay in the shaders that need them.)
"""

from __future__ import annotations

import numpy as np

from probeless.errors import ProbelessError


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """sRGB-encoded values (0..1) -> linear (0..1), elementwise.

    Not clipped (clip first: a negative value gives NaN). float32 stays float32, float64 and integer
    inputs give float64.
    """
    x = np.asarray(x)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """Linear values -> sRGB-encoded 0..1, elementwise; clipped to 0..1 first (over-exposed = white).

    float32 stays float32, float64 and integer inputs give float64.
    """
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


_FROM8 = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


def from_srgb8(codes: np.ndarray) -> np.ndarray:
    """8-bit sRGB codes (uint8 0..255, any shape) -> linear float32 0..1 (a 256-entry table, exact to float32).

    Other integer or float inputs are taken as codes 0..255 too (scaled by 1/255, then decoded).
    """
    c = np.asarray(codes)
    if c.dtype == np.uint8:
        return _FROM8[c]
    return srgb_to_linear(c.astype(np.float32) / np.float32(255.0)).astype(np.float32)


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear values (any shape) -> 8-bit sRGB codes (uint8 0..255): NaN -> 0, clipped to 0..1, encoded,
    rounded to the nearest code. Computed in float32 (float64 input: in float64)."""
    x = np.asarray(linear)
    x = x.astype(np.float64 if x.dtype == np.float64 else np.float32)
    s = linear_to_srgb(np.nan_to_num(x, nan=0.0))
    return np.round(s * 255).astype(np.uint8)


def quantize8(values: np.ndarray) -> np.ndarray:
    """Values already in their encoding (e.g. sRGB values 0..1) -> uint8 codes 0..255: rounded, clipped; no curve."""
    return np.clip(np.round(np.asarray(values) * 255.0), 0, 255).astype(np.uint8)


REC709_Y = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)  # CIE Y of linear Rec.709 / sRGB primaries


def luminance(rgb: np.ndarray) -> np.ndarray:
    """CIE Y of linear Rec.709 RGB: (..., 3) -> (...,) float32, ``0.2126 R + 0.7152 G + 0.0722 B``."""
    a = np.asarray(rgb, dtype=np.float32)
    if a.ndim < 1 or a.shape[-1] != 3:
        raise ProbelessError(f"luminance: expected an (..., 3) RGB array, got shape {a.shape}")
    return a @ REC709_Y


def reinhard(radiance: np.ndarray) -> np.ndarray:
    """Reinhard tone map per channel, ``x / (1 + x)``: linear radiance >= 0 (unbounded; negatives to 0) ->
    linear 0..1, for showing HDR values on LDR displays (exports, viewers)."""
    r = np.maximum(np.asarray(radiance, np.float32), 0.0)
    return r / (1.0 + r)
