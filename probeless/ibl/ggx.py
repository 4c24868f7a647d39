"""GGX prefiltering of a cubemap (split-sum radiance, Karis 2013) as an exact sum over texels.

:func:`ggx_prefilter` gives the level an :class:`~probeless.ibl.lighting.Lighting` hands the IBL renderer for a
GGX material of some roughness (the renderer's own fallback, a box mip chain, is not GGX).
"""

from __future__ import annotations

import numpy as np

from probeless.errors import ProbelessError

GGX_FACE = 32  # default face size of the prefiltered level [px]

_GGX_WEIGHTS: dict[tuple[int, float], np.ndarray] = {}


def ggx_weights(size: int, roughness: float) -> np.ndarray:
    """(6 S², 6 S²) float32 row-stochastic GGX prefilter matrix of an S = ``size`` cubemap (cached).

    Row r (output direction, n = v = r) weights input texel l by D(h) max(n.l, 0) dω_l, h = (r + l) / |r + l|,
    D(h) = alpha² / (pi ((n.h)² (alpha² - 1) + 1)²), alpha = roughness², (n.h)² = (1 + n.l) / 2: the
    split-sum prefiltered radiance of Karis (2013) as an exact sum over texels instead of importance samples.
    """
    key = (int(size), float(roughness))
    if key not in _GGX_WEIGHTS:
        from probeless.geom.cube import cube_directions, cube_solid_angles

        d = cube_directions(size).reshape(-1, 3).astype(np.float32)
        omega = cube_solid_angles(size).reshape(-1).astype(np.float32)
        a2 = np.float32(max(float(roughness), 1e-3) ** 4)
        out = np.empty((len(d), len(d)), np.float32)
        for i in range(0, len(d), 1024):
            cos = np.maximum(d[i:i + 1024] @ d.T, np.float32(0))  # n.l; 0 below the horizon
            den = (np.float32(0.5) + np.float32(0.5) * cos) * (a2 - 1) + 1  # (n.h)^2 (alpha^2 - 1) + 1
            w = cos * omega / (den * den)  # D(h) up to the constant alpha^2 / pi, which the row sum removes
            out[i:i + 1024] = w / w.sum(axis=1, keepdims=True)
        _GGX_WEIGHTS[key] = out
    return _GGX_WEIGHTS[key]


def ggx_prefilter(faces: np.ndarray, roughness: float, size: int = GGX_FACE) -> np.ndarray:
    """(6, s, s, 3) float32 GGX-prefiltered radiance of ``faces`` (6, S, S, 3), s = min(S, ``size``) (S is box
    averaged down to s first; S must be a multiple of s)."""
    f = np.asarray(faces, np.float32)
    s = min(f.shape[1], size)
    k = f.shape[1] // s
    if k * s != f.shape[1]:
        raise ProbelessError(f"ggx_prefilter: face size {f.shape[1]} is not a multiple of {s}")
    f = f.reshape(6, s, k, s, k, -1).mean(axis=(2, 4))
    return (ggx_weights(s, roughness) @ f.reshape(6 * s * s, -1)).reshape(f.shape).astype(np.float32)
