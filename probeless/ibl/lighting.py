"""The lighting of one virtual object in linear units: cubemap faces, prefiltered levels and SH.

An envmap message is either linear radiance (``linear=True``) or the fisheye's sRGB-encoded LDR
output (``linear=False``, uint8 0..255 or float 0..1). Lighting is computed in linear units, so LDR
maps are decoded here; SH coefficients must be in the same linear units as the decoded map.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from probeless.color import srgb_to_linear
from probeless.envmap.sh import project_cubemap
from probeless.errors import SchemaError
from probeless.messages.lighting import Cubemap, SHCoefficients


@dataclass(frozen=True)
class Lighting:
    """Linear radiance around one object."""

    faces: np.ndarray                                # (6, S, S, 3) float32 linear
    sh: np.ndarray                                   # (bands^2, 3) float64 SH radiance, same units
    # explicit prefiltered levels (roughness, (6, s, s, 3) float32): the renderer then reads the lobe from them as
    # they are (no Fresnel, no masking: the probes' definition, probeless.ibl.probes); () = importance-sampled GGX
    levels: tuple[tuple[float, np.ndarray], ...] = ()


def linear_faces(faces: np.ndarray, linear: bool) -> np.ndarray:
    """(6, S, S, 3) float32 linear faces of a cubemap array (alpha dropped, sRGB decoded when not linear)."""
    f = np.asarray(faces)[..., :3]
    if linear:
        return f.astype(np.float32)
    scaled = f.astype(np.float32) / (255.0 if f.dtype == np.uint8 else 1.0)
    return srgb_to_linear(np.clip(scaled, 0.0, 1.0)).astype(np.float32)


def lighting_from_messages(envmap: Cubemap, sh: SHCoefficients | None = None) -> Lighting:
    """The :class:`Lighting` of an envmap message and its SH (projected from the map when ``sh`` is None).

    The message's ``mips`` are not used: the renderer builds the mip chain of the linear faces itself and
    importance-samples the GGX lobe from it (box mips read at a roughness level are no GGX prefilter, and an LDR
    message's mips were averaged in sRGB).
    """
    faces = linear_faces(envmap.faces, envmap.linear)
    if sh is None:
        coeffs = project_cubemap(faces, 5)
    else:
        if sh.object_id != envmap.object_id:
            raise SchemaError(f"SH of object {sh.object_id!r} given with the envmap of {envmap.object_id!r}")
        coeffs = np.asarray(sh.coeffs, np.float64)
    return Lighting(faces, coeffs)


def glossy_faces(lighting: Lighting, roughness: float) -> np.ndarray | None:
    """Faces prefiltered for ``roughness``, blended between the two bracketing levels; None without levels.

    The base faces count as roughness 0. Levels of a different size than their neighbour are not
    blended: the nearer one is taken.
    """
    if not lighting.levels or roughness <= 0:
        return None
    levels = [(0.0, lighting.faces), *lighting.levels]
    for (r0, f0), (r1, f1) in itertools.pairwise(levels):
        if r0 <= roughness <= r1:
            t = (roughness - r0) / (r1 - r0) if r1 > r0 else 0.0
            if f0.shape == f1.shape:
                return ((1 - t) * f0 + t * f1).astype(np.float32)
            return f0 if t < 0.5 else f1
    return levels[-1][1]
