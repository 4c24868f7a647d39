"""Inverse tone mapping operators (LDR 0..1 -> HDR radiance), numpy float32, per frame.

All operators take an (..., 3) image with values in 0..1 and keep its shape; the output is
float32. Colour is expanded by the luminance ratio ``out = ldr * Lw / Ld`` (0 where ``Ld = 0``).

* ``paper``: Iorns & Rhee (paper 002) Eq. 1-3, applied to the pixel values as stored (the paper
  says "values between 0.0 and 1.0" and does not linearise, so neither do we).
* ``landis``: Landis 2002 expansion of the top of the range (Banterle et al., "Advanced High
  Dynamic Range Imaging", 2011, Sec. 5.1).
* ``akyuz``: Akyuz et al. 2007 linear / gamma scaling of the frame's normalised luminance.
* ``banterle``: Banterle et al. 2006 inverse Reinhard plus an expand map, simplified (see there).

The last three are defined on linear values; decode gamma first (:func:`gamma_decode`) if wanted.
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.color import REC709_Y
from probeless.errors import ProbelessError

_PAPER = np.array([0.3, 0.59, 0.11], dtype=np.float32)
# the simulated camera of the ITMO evaluation (itmo_maps.camera_exposure): this percentile of the HDR
# luminance is exposed to this linear value (here, not there: the command line offers them)
EXPOSURE_PERCENTILE, EXPOSURE_TARGET = 0.9, 0.5


def _as_ldr(ldr: np.ndarray, what: str) -> np.ndarray:
    a = np.asarray(ldr, dtype=np.float32)
    if a.ndim < 1 or a.shape[-1] != 3:
        raise ProbelessError(f"{what}: expected an (..., 3) RGB image, got shape {a.shape}")
    return a


def _scale_by_luminance(ldr: np.ndarray, ld: np.ndarray, lw: np.ndarray) -> np.ndarray:
    ratio = np.divide(lw, ld, out=np.zeros_like(ld), where=ld > 0)
    return (ldr * ratio[..., None]).astype(np.float32)


def gamma_decode(ldr: np.ndarray, gamma: float = 2.2) -> np.ndarray:
    """float32 ``ldr ** gamma`` (display-referred 0..1 values to linear)."""
    return np.power(np.clip(np.asarray(ldr, dtype=np.float32), 0.0, 1.0), np.float32(gamma))


def paper_itmo(ldr: np.ndarray) -> np.ndarray:
    """Eq. 1-3: ``L = 0.3 R + 0.59 G + 0.11 B``, ``Ls = 10 L^10 + 1.8``, ``out = Ls * ldr``."""
    a = _as_ldr(ldr, "paper_itmo")
    lum = a @ _PAPER
    ls = np.float32(10.0) * lum ** 10 + np.float32(1.8)
    return (a * ls[..., None]).astype(np.float32)


def landis_itmo(ldr: np.ndarray, max_lum: float = 10.0, threshold: float = 0.5,
                alpha: float = 2.0) -> np.ndarray:
    """Landis: ``Lw = (1 - k) Ld + k max_lum Ld`` with ``k = ((Ld - R) / (1 - R))^alpha`` above ``R``.

    Below ``threshold`` (R) the luminance is kept; at ``Ld = 1`` it becomes ``max_lum``.
    """
    if not 0.0 <= threshold < 1.0:
        raise ProbelessError(f"landis_itmo: threshold must be in [0, 1), got {threshold}")
    a = _as_ldr(ldr, "landis_itmo")
    ld = a @ REC709_Y
    k = (np.clip(ld - threshold, 0.0, None) / np.float32(1.0 - threshold)) ** np.float32(alpha)
    lw = (1.0 - k) * ld + k * np.float32(max_lum) * ld
    return _scale_by_luminance(a, ld, lw.astype(np.float32))


def akyuz_itmo(ldr: np.ndarray, max_lum: float = 10.0, gamma: float = 1.0) -> np.ndarray:
    """Akyuz: ``Lw = max_lum ((Ld - min) / (max - min))^gamma`` over the frame's luminance range."""
    a = _as_ldr(ldr, "akyuz_itmo")
    ld = a @ REC709_Y
    lo, hi = float(ld.min(initial=0.0)), float(ld.max(initial=0.0))
    if hi <= lo:  # a flat frame has no range to stretch: map it to max_lum * Ld
        norm = ld
    else:
        norm = (ld - np.float32(lo)) / np.float32(hi - lo)
    lw = np.float32(max_lum) * norm ** np.float32(gamma)
    return _scale_by_luminance(a, ld, lw.astype(np.float32))


def inverse_reinhard(ld: np.ndarray, max_lum: float, l_white: float) -> np.ndarray:
    """Banterle's inverse of Reinhard's global operator: 0 -> 0, 1 -> ``max_lum``, increasing."""
    ld = np.asarray(ld, dtype=np.float32)
    lw2 = np.float32(l_white) ** 2
    root = np.sqrt((1.0 - ld) ** 2 + 4.0 * ld / lw2)
    return (0.5 * np.float32(max_lum * l_white) * (ld - 1.0 + root)).astype(np.float32)


def banterle_expand_map(ldr: np.ndarray, max_lum: float = 10.0, l_white: float = 10.0,
                        threshold: float = 0.9, sigma_frac: float = 0.02) -> np.ndarray:
    """Banterle 2006, simplified: ``Lw = Ld (1 - E) + invReinhard(Ld) E``.

    Simplifications: the expand map ``E`` is a Gaussian blur (sigma ``sigma_frac * width``) of the
    mask ``Ld > threshold`` normalised to max 1, instead of the paper's density estimation of
    median-cut light sources, and it is not edge-stopped by a cross-bilateral filter.
    The image must be (H, W, 3).
    """
    a = _as_ldr(ldr, "banterle_expand_map")
    if a.ndim != 3:
        raise ProbelessError(f"banterle_expand_map: expected an (H, W, 3) image, got shape {a.shape}")
    ld = a @ REC709_Y
    mask = (ld > threshold).astype(np.float32)
    sigma = max(float(sigma_frac) * a.shape[1], 1e-3)
    e = cv2.GaussianBlur(mask, (0, 0), sigmaX=sigma, borderType=cv2.BORDER_REFLECT)
    if e.max() > 0:
        e = e / e.max()
    lw = ld * (1.0 - e) + inverse_reinhard(ld, max_lum, l_white) * e
    return _scale_by_luminance(a, ld, lw.astype(np.float32))


ITMO = {"paper": paper_itmo, "landis": landis_itmo, "akyuz": akyuz_itmo, "banterle": banterle_expand_map}


def get_itmo(name: str):
    """The operator called ``name`` from :data:`ITMO`, else a ProbelessError listing the choices."""
    try:
        return ITMO[name]
    except KeyError:
        raise ProbelessError(f"unknown inverse tone mapping operator {name!r}; choices: "
                             f"{', '.join(sorted(ITMO))}") from None


def apply_itmo(name: str, ldr: np.ndarray, **params) -> np.ndarray:
    """Run the operator ``name`` on ``ldr`` with its keyword ``params``."""
    return get_itmo(name)(ldr, **params)
