"""What the renderer draws: triangle-soup surfaces with materials, and area lights.

World frame: metres, z up, floor at z = 0. Every surface is a triangle soup (3 vertices per
triangle, counter-clockwise seen from the side its normals point to). Emissive surfaces (windows,
light panels) are drawn with their radiance and do not cast shadows; each area light also lights
the other surfaces (diffuse) with shadows.

Shading model (what the renderer computes, with ``s_i`` the on/off scale of light ``i``)::

    L(x) = albedo(x) / pi * sum_i s_i * E_i(x) + albedo(x) * sum_i s_i * ambient_i
    E_i(x) = sum over an n x n grid of sample points p on light i of
             radiance_i * (area_i / n^2) * max(0, cos_light) * max(0, cos_surface) / max(|p - x|^2, eps) * V_i(x)

``V_i`` is visibility from the light's centre (a cube shadow map). An emissive surface shows
``emission * s_light_index`` (or ``emission`` when ``light_index`` is -1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Surface:
    """One drawable part of the scene with a single material."""

    name: str                 # e.g. "wall1", "floor", "ceiling", "window0", "light1", "furniture0"
    positions: np.ndarray     # (3T, 3) float32 triangle soup [m, world]
    normals: np.ndarray       # (3T, 3) float32 unit normals, pointing to the visible side [world]
    uvs: np.ndarray           # (3T, 2) float32 texture coordinates in texture repeats (metres / tile_m) [-]
    color: np.ndarray         # (3,) float32 linear albedo, multiplies the texture if any [0..1]
    texture: np.ndarray | None = None  # (H, W, 3) float32 linear albedo texture, tiled with GL_REPEAT; None = plain
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # (3,) emitted radiance [linear]
    light_index: int = -1     # index of the AreaLight this panel shows; its emission follows that light's on/off

    @property
    def emissive(self) -> bool:
        """True for windows and light panels (drawn with their radiance, no shading, no shadow casting)."""
        return bool(np.any(self.emission > 0))


@dataclass(frozen=True)
class AreaLight:
    """A rectangular emitter lighting the room: ceiling panel or window."""

    name: str                 # e.g. "light0", "window1"
    center: np.ndarray        # (3,) float64 rectangle centre [m, world]
    half_u: np.ndarray        # (3,) float64 half-extent vector along the rectangle's first side [m, world]
    half_v: np.ndarray        # (3,) float64 half-extent vector along the second side [m, world]
    normal: np.ndarray        # (3,) float64 unit direction the light emits into (into the room) [world]
    radiance: np.ndarray      # (3,) float64 emitted radiance when on [linear]
    # (3,) radiance this light adds everywhere when on, standing in for interreflection [linear]
    ambient: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def area(self) -> float:
        """Rectangle area [m^2]."""
        return float(4.0 * np.linalg.norm(self.half_u) * np.linalg.norm(self.half_v))


@dataclass(frozen=True)
class SceneGeometry:
    """Everything the renderer needs, independent of time (light on/off is passed per render call)."""

    surfaces: tuple[Surface, ...]
    lights: tuple[AreaLight, ...]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned (min, max) corners of all surfaces [m, world]."""
        pts = np.concatenate([s.positions for s in self.surfaces])
        return pts.min(axis=0), pts.max(axis=0)
