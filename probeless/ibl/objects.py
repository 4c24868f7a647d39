"""Virtual objects from parameter mappings (the compositor node's ``objects`` list).

::

    - id: teapot                      # matches the envmap / SH object_id
      mesh: /path/teapot.obj          # .obj, .ply, or "sphere" (a UV sphere)
      position: [1.0, 2.0, 0.75]      # world [m]: the centre, or the bottom centre with anchor: bottom
      radius: 0.15                    # bounding-sphere radius [m] (or scale: metres per mesh unit)
      yaw_deg: 30                     # about world z
      up: y                           # the file's up axis (y or z)
      material: {type: metal, colour: [0.95, 0.64, 0.54], roughness: 0.3}
                                      # a material with texture maps (principled) loads the mesh's UVs too
      contact_shadow: true            # differential-rendering shadow on the plane below
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from probeless.errors import SceneError
from probeless.ibl.materials import MAP_KEYS, material_from_dict
from probeless.ibl.mesh_io import load_mesh, load_mesh_uv, place
from probeless.ibl.render import IblObject

KEYS = {"id", "mesh", "position", "radius", "scale", "yaw_deg", "up", "anchor", "material", "contact_shadow",
        "floor_z", "shadow_extent", "prt_dirs"}


def object_from_dict(spec: Mapping[str, Any], where: str = "objects[0]") -> IblObject:
    """An :class:`IblObject` (mesh loaded, placed, PRT not yet computed) from its mapping (module doc)."""
    if not isinstance(spec, Mapping):
        raise SceneError(f"{where}: expected a mapping, got {spec!r}")
    unknown = set(spec) - KEYS
    missing = {"id", "mesh", "position", "material"} - set(spec)
    if unknown or missing:
        raise SceneError(f"{where}: unknown keys {sorted(unknown)}, missing keys {sorted(missing)} "
                         f"(known: {sorted(KEYS)})")
    position = np.asarray(spec["position"], np.float64)
    if position.shape != (3,) or not np.all(np.isfinite(position)):
        raise SceneError(f"{where}.position: expected [x, y, z], got {spec['position']!r}")
    mesh_path = spec["mesh"] if spec["mesh"] == "sphere" else Path(spec["mesh"])
    material = material_from_dict(spec["material"], f"{where}.material")
    textured = any(getattr(material, key, None) for key in MAP_KEYS)
    try:
        v, f, uvs = load_mesh_uv(mesh_path) if textured else (*load_mesh(mesh_path), None)
        if textured and uvs is None:
            raise SceneError(f"{mesh_path}: the material has texture maps but the mesh has no texture coordinates")
        placed = place(v, f, position, radius=spec.get("radius"), scale=float(spec.get("scale", 1.0)),
                       yaw_deg=float(spec.get("yaw_deg", 0.0)), up=spec.get("up", "y"),
                       anchor=spec.get("anchor", "center"), uvs=uvs)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    floor_z = spec.get("floor_z")
    return IblObject(str(spec["id"]), placed, material,
                     contact_shadow=bool(spec.get("contact_shadow", True)),
                     floor_z=None if floor_z is None else float(floor_z),
                     shadow_extent=float(spec.get("shadow_extent", 4.0)), prt_dirs=int(spec.get("prt_dirs", 512)))


def objects_problem(specs, resolve: Callable[[Mapping[str, Any]], Mapping[str, Any]] | None = None) -> str | None:
    """The compositor nodes' ``objects`` param rule (a param check): every spec builds (see
    :func:`object_from_dict`; ``resolve`` maps a spec first, as the node does) and the ids are unique."""
    try:
        ids = [object_from_dict(resolve(s) if resolve else s, f"objects[{i}]").id for i, s in enumerate(specs)]
    except SceneError as exc:
        return str(exc)
    if len(set(ids)) != len(ids):
        return f"object ids must be unique, got {ids}"
    return None


def material_problem(spec) -> str | None:
    """The ``material`` param rule (default material of file objects): null, or a material mapping that builds."""
    if spec is None:
        return None
    try:
        material_from_dict(spec, "material")
    except SceneError as exc:
        return str(exc)
    return None


def all_objects(params) -> list[Mapping[str, Any]]:
    """The object mappings of a node with ``objects_file`` + ``material`` + ``objects`` params: the file's objects
    (:func:`probeless.scene.objects_file.load_objects`) then the list; SceneError when an id repeats."""
    from probeless.scene.objects_file import load_objects

    specs = [*(load_objects(params.objects_file, params.material) if params.objects_file else []), *params.objects]
    ids = [s.get("id") for s in specs if isinstance(s, Mapping)]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise SceneError(f"object ids {dup} appear twice (objects_file and objects)")
    return specs
