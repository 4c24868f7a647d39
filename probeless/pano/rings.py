"""The glossy lobe and the paper's fixed ring sampling pattern (paper 002, §3.2, §5); see :mod:`.glossy`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import ProbelessError

SPACINGS = ("quantile", "uniform")
WEIGHTINGS = ("solid_angle", "phong")


def phong_exponent(roughness: float) -> float:
    """Phong exponent ``n = 2 / r^2 - 2`` of a roughness ``r`` in (0, 1] (Beckmann correspondence)."""
    r = float(roughness)
    if not 0.0 < r <= 1.0:
        raise ProbelessError(f"glossy: roughness must be in (0, 1], got {roughness!r}")
    return 2.0 / (r * r) - 2.0


def _angle_from_one_minus_cos(x: np.ndarray) -> np.ndarray:
    """``arccos(1 - x)`` without cancellation for tiny ``x`` (narrow lobes)."""
    return 2.0 * np.arcsin(np.sqrt(np.clip(x, 0.0, 2.0) / 2.0))


def lobe_half_angle(exponent: float) -> float:
    """Angle [rad] where ``cos^n`` falls to 0.5 (the paper's lobe radius); ``pi / 2`` for ``n = 0``."""
    n = float(exponent)
    if not n >= 0.0:
        raise ProbelessError(f"glossy: Phong exponent must be >= 0, got {exponent!r}")
    return float(np.pi / 2) if n == 0.0 else float(_angle_from_one_minus_cos(-np.expm1(-np.log(2.0) / n)))


def mass_to_angle(m: np.ndarray, n: float) -> np.ndarray:
    """Inverse of the lobe's CDF ``1 - cos^(n+1)(theta)`` over the hemisphere."""
    with np.errstate(divide="ignore"):
        return _angle_from_one_minus_cos(-np.expm1(np.log1p(-np.minimum(m, 1.0)) / (n + 1.0)))


def _mass(theta: np.ndarray, n: float) -> np.ndarray:
    """The lobe's CDF over the hemisphere: ``1 - cos^(n+1)(theta)``."""
    return -np.expm1((n + 1.0) * np.log(np.clip(np.cos(theta), 1e-300, 1.0)))


def _strata(n: float, inside: int, outside: int, spacing: str) -> tuple[np.ndarray, np.ndarray]:
    """Stratum edges (R + 1,) [rad] and ring radii (R,), ``inside`` strata within the lobe radius."""
    half = lobe_half_angle(n)
    if spacing == "uniform":
        far = max(float(mass_to_angle(np.array(0.99), n)), half)
        edges = np.concatenate([np.linspace(0.0, half, inside + 1), np.linspace(half, far, outside + 1)[1:]])
        return edges, 0.5 * (edges[:-1] + edges[1:])
    if n == 0.0:  # no lobe radius: the weight never falls to 0.5, so split the whole hemisphere
        mass = np.linspace(0.0, 1.0, inside + outside + 1)
    else:
        m_half = 1.0 - 0.5 ** ((n + 1.0) / n)
        mass = np.concatenate([np.linspace(0.0, m_half, inside + 1), np.linspace(m_half, 1.0, outside + 1)[1:]])
    return mass_to_angle(mass, n), mass_to_angle(0.5 * (mass[:-1] + mass[1:]), n)


@dataclass(frozen=True)
class RingPattern:
    """A fixed sampling pattern about ``R``: K samples, each an angle, azimuth, weight and mip level."""

    angles: np.ndarray    # (K,) polar angle from R [rad]
    azimuths: np.ndarray  # (K,) azimuth around R in tangent_frame's (t, b) [rad]
    weights: np.ndarray   # (K,) sum to 1
    lods: np.ndarray      # (K,) mip level for an equirect of the pattern's height at level 0


def ring_pattern(roughness: float, height: int, per_ring: int = 6, rings_inside: int = 3, rings_outside: int = 3,
                 *, spacing: str = "quantile", weighting: str = "solid_angle", twist: bool = True,
                 lod_bias: float = 0.0) -> RingPattern:
    """The ring pattern of ``roughness`` for a level-0 equirect of ``height`` rows (see module doc).

    A ring of radius ``a`` has neighbour distance ``d = 2 asin(sin a sin(pi / per_ring))``; its lod is
    ``log2(d height / pi) + lod_bias`` (texel spacing ``pi 2^lod / height`` equals ``d``), clamped
    to ``[0, floor(log2 height)]``. ``lod_bias=0`` is the paper's rule; a trilinear lookup blurs
    over about two texels, so ``lod_bias=-1`` (texel spacing d / 2) matches the measured lobe
    integral better (docs: ``probeless eval glossy``).
    """
    n = phong_exponent(roughness)
    if int(height) < 1 or per_ring < 1 or rings_inside < 1 or rings_outside < 0:
        raise ProbelessError(f"ring_pattern: need height, per_ring, rings_inside >= 1 and rings_outside >= 0, got "
                             f"{height}, {per_ring}, {rings_inside}, {rings_outside}")
    if spacing not in SPACINGS or weighting not in WEIGHTINGS:
        raise ProbelessError(f"ring_pattern: spacing must be one of {SPACINGS} and weighting one of {WEIGHTINGS}, "
                             f"got {spacing!r}, {weighting!r}")
    edges, radii = _strata(n, rings_inside, rings_outside, spacing)
    if weighting == "solid_angle":  # the Phong weight integrated over the ring's stratum
        wgt = np.diff(_mass(edges, n))
    else:
        wgt = np.exp(n * np.log(np.cos(radii)))
    dist = 2.0 * np.arcsin(np.sin(radii) * np.sin(np.pi / per_ring))
    with np.errstate(divide="ignore"):
        lod = np.clip(np.log2(dist * int(height) / np.pi) + lod_bias, 0.0, np.floor(np.log2(int(height))))
    rings = np.arange(len(radii))
    steps = np.arange(per_ring)[None, :] + 0.5 * (rings[:, None] % 2) * bool(twist)
    wgt = np.repeat(wgt, per_ring)
    f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32).reshape(-1)  # noqa: E731
    return RingPattern(angles=f32(np.repeat(radii, per_ring)), azimuths=f32(steps * (2.0 * np.pi / per_ring)),
                       weights=f32(wgt / wgt.sum()), lods=f32(np.repeat(lod, per_ring)))
