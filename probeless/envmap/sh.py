"""Real spherical harmonics on cubemaps: texel solid angles, projection, radiance and irradiance.

Basis: orthonormal real SH (Sloan, "Stupid Spherical Harmonics Tricks") with the Condon-Shortley
phase, row ``k = l (l + 1) + m`` - the convention of :class:`probeless.messages.lighting.SHCoefficients`.
So ``Y_1,-1 = -c y``, ``Y_1,0 = c z``, ``Y_1,1 = -c x`` with ``c = sqrt(3 / 4 pi)``.

Irradiance uses Ramamoorthi & Hanrahan's cosine-lobe convolution ("An Efficient Representation
for Irradiance Environment Maps", 2001): ``E(n) = sum_lm A_l L_lm Y_lm(n)`` with ``A_0 = pi``,
``A_1 = 2 pi / 3``, ``A_l = 0`` for odd ``l > 1`` and, for even ``l``,
``A_l = 2 pi (-1)^(l/2 - 1) / ((l + 2)(l - 1)) * l! / (2^l ((l/2)!)^2)``.
"""

from __future__ import annotations

import functools
from math import factorial, pi, sqrt

import numpy as np

from probeless.errors import ProbelessError
from probeless.geom.cube import cube_solid_angles, texel_direction


def _check_bands(bands: int) -> None:
    if not 1 <= int(bands) <= 16:
        raise ProbelessError(f"sh: bands must be in 1..16, got {bands}")


def sh_basis(dirs: np.ndarray, bands: int) -> np.ndarray:
    """(..., bands^2) real orthonormal SH of unit directions (..., 3) (normalised here)."""
    _check_bands(bands)
    d = np.asarray(dirs, dtype=np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-300)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    phi = np.arctan2(y, x)
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    lmax = bands - 1
    # associated Legendre P_l^m(z), Condon-Shortley phase included, by the standard recurrences
    P = {(0, 0): np.ones_like(z)}
    for m in range(1, lmax + 1):
        P[m, m] = -(2 * m - 1) * s * P[m - 1, m - 1]
    for m in range(lmax):
        P[m + 1, m] = (2 * m + 1) * z * P[m, m]
    for m in range(lmax + 1):
        for l in range(m + 2, lmax + 1):
            P[l, m] = ((2 * l - 1) * z * P[l - 1, m] - (l + m - 1) * P[l - 2, m]) / (l - m)
    out = np.empty(d.shape[:-1] + (bands * bands,), dtype=np.float64)
    for l in range(bands):
        for m in range(l + 1):
            k = sqrt((2 * l + 1) / (4 * pi) * factorial(l - m) / factorial(l + m))
            if m == 0:
                out[..., l * (l + 1)] = k * P[l, 0]
            else:
                out[..., l * (l + 1) + m] = sqrt(2.0) * k * np.cos(m * phi) * P[l, m]
                out[..., l * (l + 1) - m] = sqrt(2.0) * k * np.sin(m * phi) * P[l, m]
    return out


@functools.lru_cache(maxsize=4)
def _weighted_basis(size: int, bands: int, sub: int = 2) -> np.ndarray:
    """(6 S S, bands^2) float32 integral of the basis over every texel (cached: projection is one matmul).

    Each texel is integrated with ``sub x sub`` sub-texels, which cuts the quadrature error of
    point sampling (visible as spurious cubic-symmetric l = 4 terms) about ``sub^2``-fold.
    """
    fine = size * sub
    omega = cube_solid_angles(fine)[0]
    r, c = np.mgrid[0:fine, 0:fine]
    out = np.empty((6, size, size, bands * bands), dtype=np.float32)
    for f in range(6):
        y = sh_basis(texel_direction(f, r, c, fine), bands) * omega[..., None]
        out[f] = y.reshape(size, sub, size, sub, -1).sum(axis=(1, 3))
    return out.reshape(-1, bands * bands)


def project_cubemap(faces: np.ndarray, bands: int = 5) -> np.ndarray:
    """(bands^2, C) float64 SH coefficients of cubemap ``faces`` (6, S, S, C): sum of f Y dOmega over texels."""
    f = np.asarray(faces)
    if f.ndim != 4 or f.shape[0] != 6 or f.shape[1] != f.shape[2]:
        raise ProbelessError(f"project_cubemap: faces must be (6, S, S, C), got {f.shape}")
    _check_bands(bands)
    basis = _weighted_basis(f.shape[1], int(bands))
    return basis.T.astype(np.float64) @ f.reshape(-1, f.shape[3]).astype(np.float64)


def cosine_lobe(bands: int) -> np.ndarray:
    """(bands,) Ramamoorthi-Hanrahan A_l: SH of the clamped cosine max(0, n . w) per band."""
    a = np.zeros(bands)
    for l in range(bands):
        if l == 0:
            a[l] = pi
        elif l == 1:
            a[l] = 2 * pi / 3
        elif l % 2 == 0:
            a[l] = (2 * pi * (-1) ** (l // 2 - 1) / ((l + 2) * (l - 1))
                    * factorial(l) / (2 ** l * factorial(l // 2) ** 2))
    return a


def _bands_of(coeffs: np.ndarray) -> int:
    n = len(coeffs)
    bands = int(round(sqrt(n)))
    if bands * bands != n:
        raise ProbelessError(f"sh: {n} coefficient rows is not a square number of bands")
    return bands


def radiance_from_sh(coeffs: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(..., C) radiance reconstructed from ``coeffs`` (bands^2, C) along directions (..., 3)."""
    c = np.asarray(coeffs, dtype=np.float64)
    return sh_basis(dirs, _bands_of(c)) @ c


def irradiance_from_sh(coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(..., C) irradiance E(n) = integral of L(w) max(0, n . w) dw for normals (..., 3).

    Divide by pi for the outgoing radiance of a white Lambertian surface.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    bands = _bands_of(c)
    per_row = np.repeat(cosine_lobe(bands), [2 * l + 1 for l in range(bands)])
    return sh_basis(normals, bands) @ (c * per_row[:, None])
