"""BRDFs of the point-based GI renderer (paper 001, §5.3 eq. 9 and §6.4): numpy reference implementations.

``shaders/brdf.glsl`` computes exactly the same formulas on the GPU; the tests compare the two.

Conventions (numpy and GLSL alike):

* ``n`` is the unit surface normal, ``wi`` the unit direction *towards the light* and ``wo`` the unit direction
  *towards the viewer*, all pointing away from the surface (the BRDFs are reciprocal, so swapping them changes
  nothing). A BRDF is zero where ``n.wi <= 0`` or ``n.wo <= 0``. Values are in 1/sr; the cosine factor of the
  rendering equation is *not* included.
* ``roughness`` is the perceptual roughness r in [0, 1] (Disney / UE4): the GGX width is ``alpha = r²``, clamped to
  at least :data:`MIN_ALPHA` so a mirror-like surface stays finite.
* Arrays broadcast: directions are ``(..., 3)``, colours ``(..., 3)`` or ``(3,)``, roughness and metalness scalars or
  ``(...)``; the result of a BRDF is ``(..., 3)`` (RGB).

Microfacet specular (:func:`ggx`): Cook-Torrance ``D G F / (4 |n.wi| |n.wo|)`` with the GGX (Trowbridge-Reitz)
distribution ``D(h) = alpha² / (pi ((n.h)² (alpha² - 1) + 1)²)``, the separable Smith shadowing ``G = G1(wi) G1(wo)``
with the exact GGX ``G1(v) = 2 / (1 + sqrt(1 + alpha² tan² theta_v))`` and Schlick's Fresnel
``F = f0 + (1 - f0) (1 - wo.h)^5``. The code evaluates ``G / (4 |n.wi| |n.wo|)`` as the equal
``1 / ((c_i + s_i) (c_o + s_o))``, ``s = sqrt(alpha² + (1 - alpha²) c²)``, and the D denominator as
``|n x h|² + alpha² (n.h)²``: both stay accurate in float32 at grazing angles and for small alpha.

Disney (:func:`disney`): the subset of Burley (2012) "Physically-based shading at Disney" the renderer needs -- the
retro-reflective diffuse ``base (1 - metalness) / pi (1 + (FD90 - 1)(1 - n.wi)^5)(1 + (FD90 - 1)(1 - n.wo)^5)``,
``FD90 = 0.5 + 2 r (wi.h)²``, plus :func:`ggx` with ``f0 = mix(0.04, base, metalness)``. Not included: sheen,
clearcoat, subsurface, specular tint, anisotropy and the ``specular`` parameter (fixed at f0 = 0.04).

Sampling: :func:`sample_ggx_half` draws half-vectors with pdf ``D(h) (n.h)`` (solid angle of h);
the reflected direction ``wi = 2 (wo.h) h - wo`` then has pdf :func:`pdf_ggx_reflect`. :func:`hammersley` gives
the low-discrepancy points the shaders feed it with.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from probeless.errors import PbgiError

SHADER_DIR = Path(__file__).with_name("shaders")  # brdf.glsl and the PBGI programs that include it

MIN_ALPHA = 1e-3  # smallest GGX alpha (= roughness²) evaluated; keeps D finite for a perfect mirror
DIELECTRIC_F0 = 0.04  # Fresnel reflectance at normal incidence of the non-metal part (IOR 1.5)
MODELS = ("lambert", "ggx", "disney")


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _channel(x) -> np.ndarray:
    """A scalar-per-point array as (..., 1), so it broadcasts against RGB."""
    return np.asarray(x, np.float64)[..., None]


def _vectors(n, wi, wo) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.asarray(n, np.float64), np.asarray(wi, np.float64), np.asarray(wo, np.float64)


def alpha_from_roughness(roughness) -> np.ndarray:
    """GGX alpha of a perceptual roughness: ``max(r², MIN_ALPHA)``."""
    return np.maximum(np.asarray(roughness, np.float64) ** 2, MIN_ALPHA)


def ggx_d(alpha, n: np.ndarray, h: np.ndarray) -> np.ndarray:
    """The GGX normal distribution D(h) [1/sr] (zero where n.h <= 0); ``alpha`` is clamped to MIN_ALPHA."""
    a2 = np.maximum(np.asarray(alpha, np.float64), MIN_ALPHA) ** 2
    n, h = np.asarray(n, np.float64), np.asarray(h, np.float64)
    c = _dot(n, h)
    s = np.cross(n, h)
    den = _dot(s, s) + a2 * c * c  # = (n.h)² (alpha² - 1) + 1 for unit vectors, without cancellation
    return np.where(c > 0, a2 / (np.pi * den * den), 0.0)


def smith_g1(alpha, cos_theta) -> np.ndarray:
    """Exact Smith shadowing of GGX, ``2 / (1 + sqrt(1 + alpha² tan² theta))`` (zero for cos_theta <= 0)."""
    a2 = np.maximum(np.asarray(alpha, np.float64), MIN_ALPHA) ** 2
    c = np.asarray(cos_theta, np.float64)
    return np.where(c > 0, 2 * c / (c + np.sqrt(a2 + (1 - a2) * c * c)), 0.0)


def schlick(f0, cos_theta) -> np.ndarray:
    """Schlick's Fresnel ``f0 + (1 - f0) (1 - cos)^5``, RGB (..., 3); cos clamped to [0, 1]."""
    m = 1 - np.clip(_channel(cos_theta), 0.0, 1.0)
    f0 = np.asarray(f0, np.float64)
    return f0 + (1 - f0) * m ** 5


def lambert(base_color, n, wi, wo) -> np.ndarray:
    """Lambertian BRDF ``base / pi`` (..., 3); zero below either horizon."""
    n, wi, wo = _vectors(n, wi, wo)
    up = (_dot(n, wi) > 0) & (_dot(n, wo) > 0)
    return np.where(up[..., None], np.asarray(base_color, np.float64) / np.pi, 0.0)


def ggx(f0, roughness, n, wi, wo) -> np.ndarray:
    """Cook-Torrance GGX microfacet BRDF (module doc) with Fresnel reflectance ``f0`` (RGB) at normal incidence."""
    n, wi, wo = _vectors(n, wi, wo)
    ci, co = _dot(n, wi), _dot(n, wo)
    up = (ci > 0) & (co > 0)
    ci, co = np.where(up, ci, 1.0), np.where(up, co, 1.0)  # placeholders below the horizon: result is masked
    h = _unit(wi + wo + np.where(up[..., None], 0.0, n))
    a2 = alpha_from_roughness(roughness) ** 2
    vis = 1 / ((ci + np.sqrt(a2 + (1 - a2) * ci * ci)) * (co + np.sqrt(a2 + (1 - a2) * co * co)))
    spec = _channel(ggx_d(np.sqrt(a2), n, h) * vis) * schlick(f0, _dot(wo, h))
    return np.where(up[..., None], spec, 0.0)


def disney_diffuse(base_color, roughness, metalness, n, wi, wo) -> np.ndarray:
    """Burley's diffuse term ``base (1 - metalness) / pi fl fv`` (module doc), (..., 3)."""
    n, wi, wo = _vectors(n, wi, wo)
    ci, co = _dot(n, wi), _dot(n, wo)
    up = (ci > 0) & (co > 0)
    h = _unit(wi + wo + np.where(up[..., None], 0.0, n))
    cd = _dot(wi, h)
    fd90 = 0.5 + 2 * np.asarray(roughness, np.float64) * cd * cd
    fl = 1 + (fd90 - 1) * (1 - np.clip(ci, 0, 1)) ** 5
    fv = 1 + (fd90 - 1) * (1 - np.clip(co, 0, 1)) ** 5
    diffuse = np.asarray(base_color, np.float64) * (1 - _channel(metalness)) / np.pi * _channel(fl * fv)
    return np.where(up[..., None], diffuse, 0.0)


def disney_f0(base_color, metalness) -> np.ndarray:
    """Specular reflectance at normal incidence of the Disney subset: ``mix(0.04, base, metalness)``."""
    m = _channel(metalness)
    return DIELECTRIC_F0 * (1 - m) + np.asarray(base_color, np.float64) * m


def disney(base_color, roughness, metalness, n, wi, wo) -> np.ndarray:
    """Disney "principled" subset (module doc): :func:`disney_diffuse` + :func:`ggx` with :func:`disney_f0`."""
    return (disney_diffuse(base_color, roughness, metalness, n, wi, wo)
            + ggx(disney_f0(base_color, metalness), roughness, n, wi, wo))


def evaluate(model: str, base_color, roughness, metalness, n, wi, wo) -> np.ndarray:
    """The BRDF named ``model`` (one of :data:`MODELS`); for ``"ggx"`` the base colour is f0, metalness unused."""
    if model == "lambert":
        return lambert(base_color, n, wi, wo)
    if model == "ggx":
        return ggx(base_color, roughness, n, wi, wo)
    if model == "disney":
        return disney(base_color, roughness, metalness, n, wi, wo)
    raise PbgiError(f"unknown BRDF model {model!r} (known: {', '.join(MODELS)})")


def sample_ggx_half(u1, u2, alpha) -> np.ndarray:
    """Half-vectors (..., 3) in the local frame (z = normal) with pdf ``D(h) (n.h)`` from uniforms u1, u2 in [0, 1).

    Inverse CDF of that pdf: ``cos² theta = (1 - u1) / (1 + (alpha² - 1) u1)``, ``phi = 2 pi u2``; ``alpha`` is
    clamped to MIN_ALPHA as in :func:`ggx_d`.
    """
    a2 = np.maximum(np.asarray(alpha, np.float64), MIN_ALPHA) ** 2
    u1, u2 = np.asarray(u1, np.float64), np.asarray(u2, np.float64)
    den = (1 - u1) + a2 * u1
    cos_t, sin_t = np.sqrt((1 - u1) / den), np.sqrt(a2 * u1 / den)  # sin from its own closed form: no cancellation
    phi = 2 * np.pi * u2
    return np.stack(np.broadcast_arrays(sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t), axis=-1)


def pdf_ggx_reflect(alpha, n, wi, wo) -> np.ndarray:
    """Solid-angle pdf of ``wi = 2 (wo.h) h - wo`` when h is drawn by :func:`sample_ggx_half` (rotated to ``n``):
    ``D(h) (n.h) / (4 |wo.h|)``, ``h = normalize(wi + wo)``.

    It is a density over the whole sphere of ``wi`` and integrates to the fraction of sampled half-vectors with
    ``wo.h > 0`` (1 at normal incidence); a sample with ``wo.h <= 0`` or ``n.wi <= 0`` is one a renderer discards
    (the BRDF is 0 there too).
    """
    n, wi, wo = _vectors(n, wi, wo)
    h = _unit(wi + wo)
    return ggx_d(alpha, n, h) * np.maximum(_dot(n, h), 0.0) / (4 * np.abs(_dot(wo, h)))


def reflect(wo: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``wo`` mirrored about ``h``: ``2 (wo.h) h - wo`` (both unit, pointing away from the surface)."""
    wo, h = np.asarray(wo, np.float64), np.asarray(h, np.float64)
    return 2 * _dot(wo, h)[..., None] * h - wo


def radical_inverse2(i) -> np.ndarray:
    """Van der Corput radical inverse in base 2 of 32-bit unsigned integers (bits mirrored about the point)."""
    x = np.asarray(i, np.uint64) & np.uint64(0xFFFFFFFF)
    out = np.zeros_like(x)
    for b in range(32):
        out |= ((x >> np.uint64(b)) & np.uint64(1)) << np.uint64(31 - b)
    return out.astype(np.float64) / 2.0 ** 32


def hammersley(i, n: int) -> np.ndarray:
    """The i-th of ``n`` Hammersley points, (..., 2) in [0, 1)²: ``(i / n, radical_inverse2(i))``."""
    i = np.asarray(i)
    return np.stack([i.astype(np.float64) / n, radical_inverse2(i)], axis=-1)


def tangent_frame(n) -> np.ndarray:
    """(..., 3, 3) orthonormal frames whose columns are t, b, n (right-handed: t x b = n) for unit normals ``n``.

    Branch-free construction of Duff et al. (2017); ``frame @ local`` takes a local (z = normal) vector to world.
    """
    n = np.asarray(n, np.float64)
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    sign = np.where(z >= 0, 1.0, -1.0)
    a = -1 / (sign + z)
    b = x * y * a
    t = np.stack([1 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    bt = np.stack([b, sign + y * y * a, -y], axis=-1)
    return np.stack([t, bt, n], axis=-1)
