"""BRDF descriptions of virtual objects for the point-based GI renderer (paper 001, §5.3 and §6.4).

:func:`brdf_from_material` maps a scene material (:mod:`probeless.ibl.materials`) to the :class:`Brdf` the
micro-buffer shader evaluates with ``brdf_eval`` of ``shaders/brdf.glsl`` (model ids :data:`MODEL_IDS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from probeless.errors import PbgiError
from probeless.ibl.materials import Diffuse, Glass, Metal, Mirror, Mix, Principled
from probeless.pbgi.textures import load_material_maps

MODEL_IDS = {"lambert": 0, "ggx": 1, "disney": 2}  # = BRDF_LAMBERT, BRDF_GGX, BRDF_DISNEY of brdf.glsl
MIRROR_ROUGHNESS = 0.05  # roughness a Mirror is rendered with: a perfect mirror needs importance sampling (§6.3)


@dataclass(frozen=True)
class Brdf:
    """One object's BRDF (formulas: :mod:`probeless.pbgi.brdf`). A map, when set, replaces its constant; maps
    are looked up with the mesh UVs as in :func:`probeless.pbgi.textures.sample_map`. Equality and hashing look
    at the constants only, not at the maps."""

    model: str                                # "lambert", "ggx" or "disney" (MODEL_IDS gives the shader's id)
    base_color: tuple[float, float, float]    # linear RGB [0..1]: albedo (lambert), f0 (ggx), base colour (disney)
    roughness: float = 0.5                    # perceptual roughness, GGX alpha = roughness² [0..1]; unused by lambert
    metalness: float = 0.0                    # [0..1], disney only: f0 = mix(0.04, base, metalness)
    base_color_map: np.ndarray | None = field(default=None, compare=False)  # (H, W, 3) float32 linear RGB [0..1]
    roughness_map: np.ndarray | None = field(default=None, compare=False)   # (H, W) float32 perceptual [0..1]
    metalness_map: np.ndarray | None = field(default=None, compare=False)   # (H, W) float32 [0..1]

    def __post_init__(self):
        if self.model not in MODEL_IDS:
            raise PbgiError(f"unknown BRDF model {self.model!r} (known: {', '.join(MODEL_IDS)})")

    @property
    def model_id(self) -> int:
        """The shader's model id (``BRDF_LAMBERT`` 0, ``BRDF_GGX`` 1, ``BRDF_DISNEY`` 2)."""
        return MODEL_IDS[self.model]

    @property
    def textured(self) -> bool:
        """True when any map is set (the mesh needs UVs)."""
        return any(m is not None for m in (self.base_color_map, self.roughness_map, self.metalness_map))


def _rgb(values) -> tuple[float, float, float]:
    r, g, b = (float(x) for x in values)
    return r, g, b


def brdf_from_material(material) -> Brdf:
    """The :class:`Brdf` of a scene material: Diffuse -> lambert (albedo; ``shadowed`` is ignored: PBGI shadows
    by itself), Metal -> ggx (f0 = colour, its roughness), Mirror -> ggx (f0 = colour, roughness
    :data:`MIRROR_ROUGHNESS` = 0.05), Principled -> disney (maps read from disk with
    :func:`~probeless.pbgi.textures.load_material_maps`). Glass and Mix have no PBGI BRDF: :class:`PbgiError`.
    """
    if isinstance(material, Diffuse):
        return Brdf("lambert", _rgb(material.albedo), roughness=1.0)
    if isinstance(material, Metal):
        return Brdf("ggx", _rgb(material.colour), roughness=float(material.roughness))
    if isinstance(material, Mirror):
        return Brdf("ggx", _rgb(material.colour), roughness=MIRROR_ROUGHNESS)
    if isinstance(material, Principled):
        return Brdf("disney", _rgb(material.base_color), roughness=float(material.roughness),
                    metalness=float(material.metalness), **load_material_maps(material))
    if isinstance(material, (Glass, Mix)):
        raise PbgiError(f"PBGI renders opaque single-BRDF materials only (diffuse, metal, mirror, principled); "
                        f"got {type(material).__name__.lower()}: {material!r}")
    raise PbgiError(f"not a material: {material!r}")


_RENDERED_AS = (("diffuse", Diffuse, "Lambert; 'shadowed' is ignored (PBGI shadows by itself)"),
                ("metal", Metal, "GGX, f0 = colour"),
                ("mirror", Mirror, f"GGX, f0 = colour, roughness {MIRROR_ROUGHNESS}"),
                ("principled", Principled, "Disney-style: f0 = mix(0.04, base_color, metalness); maps are "
                                           "image files read with the mesh UVs (base colour sRGB, others linear)"))


def material_help() -> str:
    """The materials ``probeless pbgi render --material`` takes: each type, its keys with their defaults, and the
    roughness convention (text for ``--help``, built from the material dataclasses so it lists every key)."""
    from dataclasses import MISSING, fields

    def value(v) -> str:
        return "[" + ", ".join(f"{x:g}" for x in v) + "]" if isinstance(v, tuple) else str(v)

    lines = ["materials (--material '{type: T, key: value, ...}'; missing keys take the defaults shown):",
             "  roughness is perceptual, 0..1: GGX alpha = roughness^2 (0: mirror-like, 1: coarsest)"]
    for name, cls, how in _RENDERED_AS:
        keys = ", ".join(f"{f.name} {value(f.default)}" if f.default is not MISSING else f.name for f in fields(cls))
        lines += [f"  {name:<11} {keys}", f"  {'':<11} -> {how}"]
    lines.append("  glass, mix  not rendered by PBGI (opaque single-BRDF materials only)")
    lines.append("  e.g. '{type: metal, colour: [0.95, 0.64, 0.54], roughness: 0.3}'")
    return "\n".join(lines)
