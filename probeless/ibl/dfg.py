"""The split-sum environment-BRDF (DFG) table of GGX: directional albedo of the specular lobe, cached.

For a view at cosine ``mu`` to the normal and perceptual roughness ``r`` (GGX alpha = r²), the single-scattering
GGX lobe (Smith masking, Schlick Fresnel ``F = f0 + (f90 - f0) (1 - v.h)^5``) reflects the fraction
``E(f0, f90) = f0 A + f90 B`` of a constant environment (Karis 2013's split sum, with f90 as Filament writes it):

    A = ∫ (1 - (1 - v.h)^5) f_ss cos_l dl,   B = ∫ (1 - v.h)^5 f_ss cos_l dl,   E_ss = A + B (white surface).

The IBL shader (``ibl_specular.glsl``) uses E_ss for Filament's multiple-scattering compensation
``1 + f0 (1 / E_ss - 1)``. The table is integrated once per process in numpy (visible-normal importance sampling,
Hammersley points) and uploaded as a small float texture.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

DFG_SIZE = 32       # table side: mu and roughness each sampled at i / (DFG_SIZE - 1) [count] (ibl_specular.glsl)
DFG_SAMPLES = 2048  # samples per entry [count]
MIN_ALPHA = 1e-4    # the smallest alpha (ibl_specular.glsl's IBL_MIN_ALPHA)


def _hammersley(n: int) -> np.ndarray:
    i = np.arange(n, dtype=np.uint64)
    rev = np.zeros(n, np.uint64)
    for bit in range(32):
        rev |= ((i >> np.uint64(bit)) & np.uint64(1)) << np.uint64(31 - bit)
    return np.stack([(i + 0.5) / n, rev / 2.0 ** 32], axis=-1)


def smith_g1(alpha, c):
    """Smith G1 of GGX for a direction at cosine ``c`` to the normal."""
    a2 = np.asarray(alpha, np.float64) ** 2
    return 2 * c / (c + np.sqrt(a2 + (1 - a2) * c * c))


def dfg_terms(mu: np.ndarray, roughness: np.ndarray, samples: int = DFG_SAMPLES) -> np.ndarray:
    """(..., 2) float64 (A, B) of the module doc for views at cosine ``mu`` and perceptual ``roughness`` (broadcast)."""
    mu, r = np.broadcast_arrays(np.asarray(mu, np.float64), np.asarray(roughness, np.float64))
    alpha = np.maximum(r * r, MIN_ALPHA)[..., None]
    u = _hammersley(samples)
    v = np.stack([np.sqrt(np.maximum(0, 1 - mu * mu)), np.zeros_like(mu), mu], axis=-1)[..., None, :]
    # Heitz (2018) visible-normal sampling in the local frame (z = normal)
    vh = np.concatenate([alpha[..., None] * v[..., :2], v[..., 2:]], axis=-1)
    vh = vh / np.linalg.norm(vh, axis=-1, keepdims=True)
    lensq = vh[..., 0] ** 2 + vh[..., 1] ** 2
    t1 = np.where(lensq[..., None] > 0, np.stack([-vh[..., 1], vh[..., 0], 0 * lensq], -1)
                  / np.sqrt(np.maximum(lensq, 1e-300))[..., None], [1.0, 0.0, 0.0])
    t2 = np.cross(vh, t1)
    rr, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    p1, p2 = rr * np.cos(phi), rr * np.sin(phi)
    s = 0.5 * (1 + vh[..., 2])
    p2 = (1 - s) * np.sqrt(np.maximum(0, 1 - p1 * p1)) + s * p2
    nh = p1[..., None] * t1 + p2[..., None] * t2 + np.sqrt(np.maximum(0, 1 - p1 ** 2 - p2 ** 2))[..., None] * vh
    h = np.concatenate([alpha[..., None] * nh[..., :2], np.maximum(nh[..., 2:], 1e-9)], axis=-1)
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    vdh = np.maximum(np.sum(v * h, axis=-1), 0)
    nl = 2 * vdh * h[..., 2] - v[..., 2]
    w = np.where(nl > 0, smith_g1(alpha, np.maximum(nl, 1e-12)), 0.0)
    fc = (1 - vdh) ** 5
    return np.stack([(w * (1 - fc)).mean(axis=-1), (w * fc).mean(axis=-1)], axis=-1)


@lru_cache(maxsize=1)
def dfg_table() -> np.ndarray:
    """(DFG_SIZE, DFG_SIZE, 2) float32 (A, B): row = roughness index, column = mu index, each at i / (size - 1)
    (mu at least 1e-3); the shader reads texel centres (``ibl_dfg``), so 0 and 1 are exact, not clamped."""
    x = np.arange(DFG_SIZE) / (DFG_SIZE - 1)
    # one roughness row at a time: the same sums, twice as fast as the whole table at once (its temporaries are
    # ~50 MB each, outside the caches); every node with an IblRenderer pays this at start
    return np.stack([dfg_terms(np.maximum(x, 1e-3), r) for r in x]).astype(np.float32)


def energy_compensation(mu, roughness, f0) -> np.ndarray:
    """Filament's multiple-scattering factor ``1 + f0 (1 / E_ss - 1)`` (numpy, for checks and figures)."""
    a, b = np.moveaxis(dfg_terms(mu, roughness), -1, 0)
    return 1 + np.asarray(f0, np.float64) * (1 / (a + b) - 1)
