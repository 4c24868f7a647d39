"""The paper's Figure 6 as a picture: glossy spheres by ring sampling (top row) over Monte Carlo (bottom row).

Tone map (the same for every panel, so rows and columns compare): radiance is scaled so that the
mean luminance of all Monte Carlo sphere pixels is 0.5, compressed per channel by Reinhard's
``x / (1 + x)``, then sRGB-encoded to 8 bits; the background is black.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from probeless.color import to_srgb8
from probeless.errors import ProbelessError
from probeless.pano import glossy
from probeless.pano.sources import read_panorama
from probeless.pano.spheres import sphere_view

ROUGHNESS = (0.01, 0.05, 0.1, 0.2, 0.5)  # the paper's Figure 6
LUMA = np.array([0.3, 0.59, 0.11])  # the paper's Eq. 1 luminance
LABEL_H = 20


def tone_map(rgb: np.ndarray, exposure: float) -> np.ndarray:
    """uint8 sRGB of linear ``rgb`` times ``exposure``, Reinhard-compressed per channel."""
    x = np.maximum(np.asarray(rgb, np.float64) * exposure, 0.0)
    return to_srgb8(x / (1.0 + x))


def glossy_spheres(hdr: np.ndarray, roughness=ROUGHNESS, size: int = 128, mc_samples: int = 512, seed: int = 0,
                   forward=(1.0, 0.0, 0.0)) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(ring, mc): per roughness an (S, S, 3) float32 linear image of the glossy sphere."""
    view = sphere_view(size, forward)
    levels = glossy.mip_levels(hdr)
    ring = [view.image(glossy.glossy_ring(levels, view.reflect, r)) for r in roughness]
    mc = [view.image(glossy.glossy_mc(hdr, view.reflect, r, mc_samples, rng=seed)) for r in roughness]
    return ring, mc


def glossy_figure(hdr, out_png: str, roughness=ROUGHNESS, size: int = 128, mc_samples: int = 512, seed: int = 0,
                  forward=(1.0, 0.0, 0.0)) -> np.ndarray:
    """Write the figure (one column per roughness, ring top, MC bottom) to ``out_png``; returns it (RGB uint8).

    ``hdr``: an (H, 2H, 3) linear float32 panorama or a path :func:`read_panorama` reads.
    """
    img = read_panorama(str(hdr), linear=True) if isinstance(hdr, (str, Path)) else np.asarray(hdr, np.float32)
    ring, mc = glossy_spheres(img, roughness, size, mc_samples, seed, forward)
    mask = sphere_view(size, forward).mask
    mean_y = float(np.mean([(m[mask] @ LUMA).mean() for m in mc]))
    if not mean_y > 0:
        raise ProbelessError("glossy_figure: the panorama is black, nothing to show")
    cols = []
    for r, top, bottom in zip(roughness, ring, mc):
        label = np.zeros((LABEL_H, size, 3), np.uint8)
        cv2.putText(label, f"r={r:g}", (4, LABEL_H - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1,
                    cv2.LINE_AA)
        cols.append(np.concatenate([label, tone_map(top, 0.5 / mean_y), tone_map(bottom, 0.5 / mean_y)]))
    fig = np.concatenate(cols, axis=1)
    for text, y in (("ring", LABEL_H + 14), (f"MC {mc_samples}", LABEL_H + size + 14)):
        cv2.putText(fig, text, (4, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 0), 1, cv2.LINE_AA)
    Path(out_png).parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out_png), np.ascontiguousarray(fig[..., ::-1])):
        raise ProbelessError(f"glossy_figure: cannot write {out_png}")
    return fig
