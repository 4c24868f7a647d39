"""Materials of virtual objects, each a small frozen parameter set, and their combination.

:class:`Principled` is the Disney-style base colour / roughness / metalness material (evaluated exactly by the
point-based GI renderer, probeless.pbgi); this IBL renderer reduces it to one :class:`Shading` like the others
and ignores its texture maps (it uses the constant values).

Every material reduces to one :class:`Shading`: a diffuse term (albedo times SH irradiance / pi, or
shadowed PRT), one specular GGX lobe (alpha = roughness², Schlick Fresnel from the colour at normal incidence to
white at grazing, Smith masking, Filament's multiple-scattering compensation; a mirror is roughness 0) and a
refraction term (tint times the environment along the refracted ray, mixed with
the reflection by the exact dielectric Fresnel factor). Refraction is a single interface: the ray
bends once entering the surface and then reads the environment; it does not exit through the back.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from probeless.errors import SceneError

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Mirror:
    colour: RGB = (1.0, 1.0, 1.0)   # reflectance at normal incidence per channel (Schlick f0) [0..1]


@dataclass(frozen=True)
class Metal:
    colour: RGB = (0.95, 0.64, 0.54)  # reflectance at normal incidence per channel (Schlick f0; copper) [0..1]
    roughness: float = 0.3            # perceptual roughness: GGX alpha = roughness², 0 = mirror [0..1]


@dataclass(frozen=True)
class Glass:
    ior: float = 1.5                  # index of refraction (water 1.33) [-]
    tint: RGB = (1.0, 1.0, 1.0)       # transmittance per channel [0..1]


@dataclass(frozen=True)
class Diffuse:
    albedo: RGB = (0.8, 0.8, 0.8)     # Lambertian albedo per channel [0..1]
    shadowed: bool = False            # True = per-vertex shadowed PRT (self-occlusion), else SH irradiance


@dataclass(frozen=True)
class Principled:
    """Disney "principled" subset: metals tint their specular, non-metals reflect 4 % plus a diffuse base colour.

    A map, when given, replaces the constant in the PBGI renderer (which reads it; UVs from the mesh): the base
    colour map is sRGB-encoded (8/16 bit) or linear (float files), roughness and metalness maps are linear 0..1.
    """

    base_color: RGB = (0.8, 0.8, 0.8)  # linear base colour per channel: albedo, or f0 of a metal [0..1]
    roughness: float = 0.5             # perceptual roughness (GGX alpha = roughness²) [0..1]
    metalness: float = 0.0             # 0 = dielectric (f0 0.04), 1 = metal (f0 = base colour) [0..1]
    base_color_map: str | None = None  # image file of the base colour (sRGB) or None
    roughness_map: str | None = None   # image file of the roughness (linear, first channel) or None
    metalness_map: str | None = None   # image file of the metalness (linear, first channel) or None


@dataclass(frozen=True)
class Mix:
    layers: tuple[tuple[float, Any], ...]  # (weight, material) pairs, summed


@dataclass(frozen=True)
class Shading:
    """What the shader evaluates: ``kd * diffuse + specular(ks, f90, roughness) + kt * transmission(ior)``.

    The specular lobe is GGX (alpha = roughness²) with Schlick's Fresnel from ``ks`` at normal incidence to ``f90``
    at grazing (f90 = the layer's weight: 1 for a whole material), and Filament's multiple-scattering compensation.
    """

    kd: np.ndarray = field(default_factory=lambda: np.zeros(3))  # diffuse albedo weight per channel
    ks: np.ndarray = field(default_factory=lambda: np.zeros(3))  # specular reflectance at normal incidence (f0)
    f90: np.ndarray = field(default_factory=lambda: np.zeros(3))  # specular reflectance at grazing incidence
    kt: np.ndarray = field(default_factory=lambda: np.zeros(3))  # transmission tint per channel
    roughness: float = 0.0
    ior: float = 1.0
    shadowed: bool = False


def shading(material, weight: float = 1.0) -> Shading:
    """The :class:`Shading` of a material (a :class:`Mix` sums its layers; one roughness and ior each)."""
    white = np.full(3, float(weight))
    if isinstance(material, Mirror):
        return Shading(ks=weight * np.array(material.colour, float), f90=white)
    if isinstance(material, Metal):
        return Shading(ks=weight * np.array(material.colour, float), f90=white, roughness=material.roughness)
    if isinstance(material, Glass):
        return Shading(kt=weight * np.array(material.tint, float), ior=material.ior)
    if isinstance(material, Diffuse):
        return Shading(kd=weight * np.array(material.albedo, float), shadowed=material.shadowed)
    if isinstance(material, Principled):  # maps ignored here (module doc)
        base, m = np.array(material.base_color, float), float(material.metalness)
        return Shading(kd=weight * base * (1 - m), ks=weight * (0.04 * (1 - m) + base * m), f90=white,
                       roughness=float(material.roughness))
    if isinstance(material, Mix):
        parts = [shading(m, weight * w) for w, m in material.layers]
        spec = {p.roughness for p in parts if p.ks.any() or p.f90.any()}
        iors = {p.ior for p in parts if p.kt.any()}
        if len(spec) > 1 or len(iors) > 1:
            raise SceneError(f"mix: at most one specular roughness and one ior, got {sorted(spec)} / {sorted(iors)}")
        return Shading(kd=sum(p.kd for p in parts), ks=sum(p.ks for p in parts), f90=sum(p.f90 for p in parts),
                       kt=sum(p.kt for p in parts),
                       roughness=spec.pop() if spec else 0.0, ior=iors.pop() if iors else 1.0,
                       shadowed=any(p.shadowed for p in parts if p.kd.any()))
    raise SceneError(f"not a material: {material!r}")


_TYPES = {"mirror": Mirror, "metal": Metal, "glass": Glass, "diffuse": Diffuse, "principled": Principled}
MAP_KEYS = ("base_color_map", "roughness_map", "metalness_map")


def material_from_dict(spec: Mapping[str, Any], where: str = "material"):
    """A material from its parameter mapping, e.g. ``{type: metal, colour: [1, .8, .4], roughness: 0.2}``.

    ``{type: mix, layers: [{weight: 0.7, type: diffuse, ...}, {weight: 0.3, type: mirror}]}`` combines.
    """
    if not isinstance(spec, Mapping) or "type" not in spec:
        raise SceneError(f"{where}: expected a mapping with a 'type' key, got {spec!r}")
    kind = spec["type"]
    rest = {k: v for k, v in spec.items() if k != "type"}
    if kind == "mix":
        layers = rest.pop("layers", None)
        if rest or not isinstance(layers, (list, tuple)) or not layers:
            raise SceneError(f"{where}: mix needs only a non-empty 'layers' list")
        out = []
        for i, layer in enumerate(layers):
            if not isinstance(layer, Mapping) or "weight" not in layer:
                raise SceneError(f"{where}.layers[{i}]: needs a 'weight'")
            sub = {k: v for k, v in layer.items() if k != "weight"}
            out.append((float(layer["weight"]), material_from_dict(sub, f"{where}.layers[{i}]")))
        return Mix(tuple(out))
    cls = _TYPES.get(kind)
    if cls is None:
        raise SceneError(f"{where}: unknown type {kind!r} (known: mix, {', '.join(_TYPES)})")
    known = {f.name for f in fields(cls)}
    unknown = set(rest) - known
    if unknown:
        raise SceneError(f"{where}: unknown keys {sorted(unknown)} for {kind} (known: {sorted(known)})")
    if kind == "principled":
        return _principled(rest, where)
    values = {k: tuple(float(x) for x in v) if isinstance(v, (list, tuple)) else v for k, v in rest.items()}
    for key in ("colour", "tint", "albedo"):
        if key in values and len(values[key]) != 3:
            raise SceneError(f"{where}.{key}: needs 3 values (RGB), got {values[key]}")
    if kind == "metal" and not 0.0 <= float(values.get("roughness", 0.3)) <= 1.0:
        raise SceneError(f"{where}.roughness: must be in [0, 1], got {values['roughness']}")
    if kind == "glass" and not float(values.get("ior", 1.5)) > 0:
        raise SceneError(f"{where}.ior: must be > 0, got {values['ior']}")
    return cls(**values)


def _principled(values: Mapping[str, Any], where: str) -> Principled:
    """A :class:`Principled` from its checked keys (known keys already checked); map files must exist."""
    out: dict[str, Any] = {}
    if "base_color" in values:
        v = values["base_color"]
        try:
            out["base_color"] = tuple(float(x) for x in v)
        except (TypeError, ValueError):
            raise SceneError(f"{where}.base_color: needs 3 numbers (linear RGB), got {v!r}") from None
        if len(out["base_color"]) != 3 or not all(0.0 <= x <= 1.0 for x in out["base_color"]):
            raise SceneError(f"{where}.base_color: needs 3 values in [0, 1] (linear RGB), got {v!r}")
    for key in ("roughness", "metalness"):
        if key in values:
            v = values[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= float(v) <= 1.0:
                raise SceneError(f"{where}.{key}: must be a number in [0, 1], got {v!r}")
            out[key] = float(v)
    for key in MAP_KEYS:
        v = values.get(key)
        if v is None:
            continue
        if not isinstance(v, str) or not v:
            raise SceneError(f"{where}.{key}: must be an image file path, got {v!r}")
        if not Path(v).is_file():
            raise SceneError(f"{where}.{key}: image file not found: {v}")
        out[key] = v
    return Principled(**out)
