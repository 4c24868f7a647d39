"""Lighting estimates: environment cubemaps, spherical-harmonic radiance and brightness corrections.

Cubemap convention (the world frame *is* the cube frame, z-up): face ``i`` is uploaded unchanged to
``GL_TEXTURE_CUBE_MAP_POSITIVE_X + i`` and sampled with the world-frame direction unchanged, i.e.
``texture(cube, dir_world)``. Face order is OpenGL's: +X, -X, +Y, -Y, +Z(up), -Z(down). Texel
``[face, row, col]`` has ``s = (col + 0.5) / size`` and ``t = (row + 0.5) / size`` and, with
``a = 2s - 1``, ``b = 2t - 1``, looks along the (unnormalised) world direction of the OpenGL table::

    +X: ( 1, -b, -a)   -X: (-1, -b,  a)   +Y: ( a,  1,  b)
    -Y: ( a, -1, -b)   +Z: ( a, -b,  1)   -Z: (-a, -b, -1)

(:func:`probeless.geom.cube.texel_direction` and its inverse, solid angles and lookup). Note the
world is z-up, so +Z is the ceiling face, -Z the floor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import SchemaError
from probeless.messages.base import Message, Struct, array, message
from probeless.messages.header import Header


@dataclass(frozen=True)
class CubemapLevel(Struct):
    """One prefiltered level: the radiance convolved for a GGX roughness (split-sum prefilter)."""

    roughness: float    # perceptual roughness this level is filtered for [0..1]
    # faces [face, row, col, channel], world
    faces: np.ndarray = array(("float16", "float32", "uint8"), (6, "s", "s", "c"))


@message("lighting/Cubemap", version=1)
@dataclass(frozen=True)
class Cubemap(Message):
    """Environment map seen from ``position``, for lighting one virtual object (see module doc)."""

    header: Header      # frame_id = "world"; stamp = the frame it was rendered for
    object_id: str      # virtual object this map lights
    position: np.ndarray = array("float64", (3,))  # cube centre (x, y, z) [m, world]
    # mirror (roughness 0) faces [face, row, col, RGB(A)], world
    faces: np.ndarray = array(("float16", "float32", "uint8"), (6, "s", "s", "c"))
    mips: tuple[CubemapLevel, ...] = ()  # prefiltered levels, increasing roughness, same dtype/channels as faces
    linear: bool = True  # True = linear HDR radiance [scene-referred]; False = display-referred LDR (sRGB)
    # texels that show something a camera observed (not inpainted, not unseen) [face, row, col], same size as
    # faces; 0 faces = not reported
    observed: np.ndarray = array("bool", (None, None, None), default_factory=lambda: np.zeros((0, 0, 0), bool))

    def validate(self) -> None:
        if len(self.observed) and self.observed.shape != self.faces.shape[:3]:
            raise SchemaError(f"Cubemap.observed: shape {self.observed.shape}, expected {self.faces.shape[:3]} "
                              "(or 0 faces: not reported)")
        if self.faces.shape[3] not in (3, 4):
            raise SchemaError(f"Cubemap.faces: expected 3 (RGB) or 4 (RGBA) channels, got {self.faces.shape[3]}")
        if not np.all(np.isfinite(self.position)):
            raise SchemaError("Cubemap.position: contains NaN or inf")
        last = 0.0
        for i, level in enumerate(self.mips):
            if level.faces.dtype != self.faces.dtype or level.faces.shape[3] != self.faces.shape[3]:
                raise SchemaError(f"Cubemap.mips[{i}].faces: {level.faces.dtype.name} with {level.faces.shape[3]} "
                                  f"channels, faces are {self.faces.dtype.name} with {self.faces.shape[3]}")
            if not (last <= level.roughness <= 1.0):
                raise SchemaError(f"Cubemap.mips[{i}].roughness: {level.roughness} not in [{last}, 1] (must increase)")
            last = level.roughness

    @property
    def size(self) -> int:
        """Edge length of the base faces [texels]."""
        return self.faces.shape[1]


@message("lighting/SHCoefficients", version=1)
@dataclass(frozen=True)
class SHCoefficients(Message):
    """Incoming radiance L(w) at an object as real spherical harmonics, w a world-frame direction.

    Orthonormal real SH basis (Sloan, "Stupid SH Tricks", with Condon-Shortley phase), row
    ``k = l * (l + 1) + m`` for band ``l`` and ``-l <= m <= l``; linear RGB radiance.
    """

    header: Header      # frame_id = "world"; stamp = the frame it was estimated for
    object_id: str      # virtual object these coefficients light
    bands: int          # number of bands l = 0 .. bands-1, e.g. 3 -> 9 rows, 5 -> 25 rows [count]
    coeffs: np.ndarray = array(("float32", "float64"), (None, 3))  # [k, RGB] coefficients [linear radiance]

    def validate(self) -> None:
        if self.bands < 1:
            raise SchemaError(f"SHCoefficients.bands: must be >= 1, got {self.bands}")
        if len(self.coeffs) != self.bands ** 2:
            raise SchemaError(f"SHCoefficients.coeffs: {len(self.coeffs)} rows, expected bands**2 = {self.bands ** 2}")


@message("lighting/BrightnessDelta", version=1)
@dataclass(frozen=True)
class BrightnessDelta(Message):
    """Change of the room's brightness measured by the fisheye camera since the lighting estimate."""

    header: Header      # stamp = fisheye frame time; frame_id = the fisheye camera's frame
    delta: np.ndarray = array("float32", (3,))  # RGB additive change [camera LDR units, 0..1 scale]
    texels_used: int        # texels that contributed to the estimate [count]
    sampled: bool           # False = no usable texels this frame; delta is then zero and meaningless

    def validate(self) -> None:
        if not np.all(np.isfinite(self.delta)):
            raise SchemaError("BrightnessDelta.delta: contains NaN or inf")
        if self.texels_used < 0:
            raise SchemaError(f"BrightnessDelta.texels_used: must be >= 0, got {self.texels_used}")
