"""Per-frame expansion of an LDR equirect frame to HDR on the CPU, and area resizing (paper 002).

The numpy path of the ``itmo`` node and of the evaluations: ``operator`` is one of ``paper``,
``landis``, ``akyuz``, ``banterle`` (:mod:`probeless.pano.itmo`), ``none`` (sRGB decode only) or
``ldr`` (values / 255 as they are).
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.color import from_srgb8
from probeless.pano import itmo


def expand_cpu(rgb8: np.ndarray, operator: str, *, linearize: bool = True, decode_gamma: float = 2.2,
               **params) -> np.ndarray:
    """(H, W, 3) float32 HDR of ``rgb8`` by ``operator`` (numpy); ``params`` go to the operator."""
    if operator == "none":
        return from_srgb8(rgb8)
    ldr = rgb8.astype(np.float32) / np.float32(255.0)
    if operator == "ldr":
        return ldr
    if operator != "paper" and linearize:
        ldr = itmo.gamma_decode(ldr, decode_gamma)
    return itmo.apply_itmo(operator, ldr, **params)


def area_resize(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """float32 area average of ``img`` to ``size`` (W, H) (cv2.INTER_AREA); as is if it already has it."""
    img = np.asarray(img, np.float32)
    if img.shape[1::-1] == tuple(size):
        return img
    return cv2.resize(img, tuple(int(s) for s in size), interpolation=cv2.INTER_AREA)
