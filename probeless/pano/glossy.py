"""Mirror and glossy specular from an equirect frame by mipmap ring sampling (paper 002, §3.2, §5).

Patterns: :mod:`probeless.pano.rings`; mip chain and trilinear lookups: :mod:`probeless.pano.mips`.

The glossy lobe is Phong's ``cos^n(angle(w, R))`` about the reflection direction ``R``. The paper
samples it with a fixed pattern: six samples per ring, three rings inside the lobe radius (where
the weight is 0.5) and three outside, each sample looked up trilinearly at the mip level whose
texel spacing matches the distance between neighbouring samples of its ring, Phong-weighted.

Choices made here; errors below are ``probeless eval glossy`` means over the four HDRIs of
``../shared/data/hdri`` at roughness 0.01 / 0.05 / 0.1 / 0.2 / 0.5, in % of the mean radiance:

* roughness -> exponent: ``n = 2 / r^2 - 2``, the Blinn-Phong exponent with the same lobe width
  as a Beckmann distribution of roughness ``r`` (Walter et al. 2007); ``r = 1`` gives ``n = 0``.
* ring radii (``spacing="quantile"``): the rings split the lobe's mass ``1 - cos^(n+1)`` into
  equal strata, ``rings_inside`` of them inside the lobe radius and ``rings_outside`` beyond it,
  each ring at the mass midpoint of its stratum (the same inverse CDF the Monte Carlo reference
  samples). ``spacing="uniform"`` spaces them evenly in angle up to where 99% of the mass lies.
* weights (``weighting="solid_angle"``): the Phong weight ``cos^n`` integrated over the solid
  angle of the ring's stratum, shared by its samples, normalised to sum 1 (equal weights for the
  quantile rings). ``cos^n(radius)`` times the stratum's solid angle (the midpoint rule) would
  give the open-ended outermost stratum, reaching to 90 degrees, nearly all the weight.
  ``weighting="phong"``: ``cos^n(radius)`` alone (over-weights the inner rings).
  Measured: 2.6 / 11.9 / 5.9 / 9.6 / 13.6 with these defaults, 4.0 / 7.8 / 13.1 / 13.7 / 16.5
  with ``phong`` weights, 2.7 / 12.4 / 6.5 / 9.4 / 13.7 with ``uniform`` radii.
* successive rings are turned by half an azimuth step (``twist``; without: 2.5 / 13.3 / 8.2 /
  10.2 / 13.8); no centre sample (K = 36).
* mip level: the paper's rule by default; ``ring_pattern(..., lod_bias=-1)`` (texel spacing half
  the sample spacing: a trilinear lookup already blurs over about two texels) measures
  0.2 / 3.0 / 3.5 / 6.1 / 14.1, and on the linear test environment ``1 + w.z`` cuts the
  over-blur error about tenfold.
"""

from __future__ import annotations

import numpy as np

from probeless.errors import ProbelessError
from probeless.pano.mips import bilinear, mip_levels, sample_equirect
from probeless.pano.rings import RingPattern, lobe_half_angle, mass_to_angle, phong_exponent, ring_pattern

__all__ = ["RingPattern", "glossy_mc", "glossy_ring", "lobe_half_angle", "mip_levels", "mirror",
           "phong_exponent", "ring_directions", "ring_pattern", "sample_equirect", "tangent_frame"]


def _unit(r: np.ndarray, what: str) -> np.ndarray:
    a = np.asarray(r, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ProbelessError(f"{what}: directions must be (N, 3), got shape {a.shape}")
    norm = np.linalg.norm(a, axis=1, keepdims=True)
    if np.any(norm == 0) or not np.all(np.isfinite(norm)):
        raise ProbelessError(f"{what}: zero-length or non-finite direction")
    return a / norm


def tangent_frame(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, b), each (N, 3), of unit ``r`` (N, 3); the fixed rule the shader copies:

    ``up = (0, 0, 1)`` if ``|r.z| < 0.999`` else ``(1, 0, 0)``; ``t = normalize(up x r)``; ``b = r x t``.
    """
    r = _unit(r, "tangent_frame")
    up = np.where(np.abs(r[:, 2:3]) < 0.999, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    t = np.cross(up, r)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(r, t)


def _around(r: np.ndarray, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(N, K, 3) directions at polar ``theta`` and azimuth ``phi`` (each (K,) or (N, K)) about (N, 3) unit r."""
    t, b = tangent_frame(r)
    st = np.sin(theta)[..., None]
    return (np.cos(theta)[..., None] * r[:, None] + st * np.cos(phi)[..., None] * t[:, None]
            + st * np.sin(phi)[..., None] * b[:, None])


def ring_directions(r: np.ndarray, pattern: RingPattern) -> np.ndarray:
    """(N, K, 3) sample directions ``cos(a) r + sin(a) (cos(az) t + sin(az) b)``."""
    r = _unit(r, "ring_directions")
    return _around(r, pattern.angles.astype(np.float64), pattern.azimuths.astype(np.float64))


def _levels(levels_or_image) -> list[np.ndarray]:
    return mip_levels(levels_or_image) if isinstance(levels_or_image, np.ndarray) else list(levels_or_image)


def mirror(levels_or_image, r: np.ndarray) -> np.ndarray:
    """(N, C) the paper's specular: bilinear lookup of level 0 along the reflection directions ``r``."""
    base = levels_or_image if isinstance(levels_or_image, np.ndarray) else list(levels_or_image)[0]
    return sample_equirect([base], _unit(r, "mirror"), 0.0)


def glossy_ring(levels, r: np.ndarray, roughness: float, pattern: RingPattern | None = None) -> np.ndarray:
    """(N, C) float32 ``sum_k w_k sample_equirect(levels, dir_k, lod_k)`` (``levels``: a mip chain or an image)."""
    levels = _levels(levels)
    r = _unit(r, "glossy_ring")
    pat = ring_pattern(roughness, levels[0].shape[0]) if pattern is None else pattern
    vals = sample_equirect(levels, ring_directions(r, pat), np.broadcast_to(pat.lods, (len(r), len(pat.lods))))
    return np.einsum("nkc,k->nc", vals.astype(np.float64), pat.weights.astype(np.float64)).astype(np.float32)


def glossy_mc(hdr: np.ndarray, r: np.ndarray, roughness: float, n_samples: int = 4096, rng=None) -> np.ndarray:
    """(N, C) float32 Monte Carlo ``int L cos^n dw / int cos^n dw`` over the hemisphere about each ``r``.

    Exact importance sampling of the lobe (``cos theta = u^(1/(n+1))``, ``phi = 2 pi v``) on a
    randomly shifted rank-1 lattice per direction (unbiased, lower variance than i.i.d. points),
    bilinear lookups in the full-resolution level 0. ``rng``: a seed or numpy Generator.
    """
    base = hdr if isinstance(hdr, np.ndarray) else list(hdr)[0]
    n, r = phong_exponent(roughness), _unit(r, "glossy_mc")
    if int(n_samples) < 1:
        raise ProbelessError(f"glossy_mc: n_samples must be >= 1, got {n_samples}")
    gen, s = np.random.default_rng(rng), int(n_samples)
    shift = gen.random((len(r), 2))
    i = np.arange(s)
    u = np.mod((i + 0.5) / s + shift[:, :1], 1.0)
    v = np.mod(i * (np.sqrt(5.0) - 1.0) / 2.0 + shift[:, 1:], 1.0)
    theta = mass_to_angle(1.0 - u, n)
    out = np.empty((len(r), base.shape[2]), dtype=np.float64)
    step = max(1, (1 << 20) // s)
    for a in range(0, len(r), step):
        d = _around(r[a:a + step], theta[a:a + step], 2.0 * np.pi * v[a:a + step])
        out[a:a + step] = bilinear(base, d.reshape(-1, 3)).reshape(len(d), s, -1).mean(axis=1)
    return out.astype(np.float32)
