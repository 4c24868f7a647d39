"""Virtual objects from a file: the ``objects_file`` param of the envmap, compositor and PBGI nodes.

Two forms are read:

* a **scene file** (``probeless scene render``'s input): its ``virtual_objects`` (``id``, ``position``,
  ``radius``, optional ``mesh`` and ``material``), each a sphere unless it names a mesh;
* an **objects file** for a real rig, a YAML mapping with one key ``objects``, a list in the
  compositor's object form (:mod:`probeless.ibl.objects`)::

      objects:
        - {id: sphere, mesh: sphere, position: [1.8, 1.5, 0.9], radius: 0.12, material: {type: mirror}}
        - {id: teapot, mesh: meshes/teapot.obj, position: [2.3, 1.4, 0.74], scale: 0.05, material: {type: diffuse}}

Relative mesh paths are resolved against the file's folder. Objects without a ``material`` get
``default_material``. Every problem raises :class:`~probeless.errors.SceneError` naming the file,
the list index and the key.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from probeless.errors import GraphError, SceneError
from probeless.launch.yamlload import load_yaml
from probeless.runtime.params import file_load_problem

DEFAULT_MATERIAL: dict[str, Any] = {"type": "mirror"}


def load_objects(path: str | Path, default_material: Mapping[str, Any] | None = None) -> list[dict[str, Any]]:
    """The objects of a scene or objects file (module doc) as compositor object mappings, in file order."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: objects file not found")
    try:
        doc = load_yaml(path)
    except GraphError as exc:
        raise SceneError(exc.format()) from None
    if not isinstance(doc, Mapping):
        raise SceneError(f"{path}: expected a mapping with 'objects' (an objects file) or a scene file")
    material = dict(default_material or DEFAULT_MATERIAL)
    if "objects" in doc:
        items = doc["objects"]
        if not isinstance(items, list):
            raise SceneError(f"{path}: 'objects' must be a list of object mappings")
        objects = [_object(o, f"{path}: objects[{i}]", path.parent, material) for i, o in enumerate(items)]
    else:
        objects = _scene_objects(path, material)
    ids = [o["id"] for o in objects]
    for i, oid in enumerate(ids):
        if oid in ids[:i]:
            raise SceneError(f"{path}: object id {oid!r} appears twice")
    return objects


def _object(spec: Any, where: str, root: Path, material: dict) -> dict[str, Any]:
    if not isinstance(spec, Mapping):
        raise SceneError(f"{where}: expected a mapping, got {spec!r}")
    for key in ("id", "position"):
        if key not in spec:
            raise SceneError(f"{where}: missing key {key!r}")
    oid = spec["id"]
    if not isinstance(oid, str) or not oid or "/" in oid:
        raise SceneError(f"{where}.id: must be a non-empty string without '/', got {oid!r}")
    pos = np.asarray(spec["position"], dtype=object)
    try:
        pos = pos.astype(np.float64)
    except (TypeError, ValueError):
        pos = np.full(0, np.nan)
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise SceneError(f"{where}.position: need 3 finite numbers [m, world], got {spec['position']!r}")
    out = dict(spec)
    out["position"] = pos.tolist()
    out.setdefault("mesh", "sphere")
    if out["mesh"] != "sphere" and not Path(out["mesh"]).is_absolute():
        out["mesh"] = str(root / out["mesh"])
    out.setdefault("material", dict(material))
    if out["mesh"] == "sphere":
        out.setdefault("radius", 0.1)
    return out


def _scene_objects(path: Path, material: dict) -> list[dict[str, Any]]:
    from probeless.scene.parse import load_scene

    scene = load_scene(path)
    out = []
    for i, o in enumerate(scene.virtual_objects):
        spec = {"id": o.id, "position": np.asarray(o.position).tolist(), "radius": float(o.radius),
                "mesh": getattr(o, "mesh", None) or "sphere"}
        if getattr(o, "material", None):
            spec["material"] = dict(o.material)
        out.append(_object(spec, f"{path}: virtual_objects[{i}]", path.parent, material))
    return out


def object_positions(objects: list[Mapping[str, Any]]) -> dict[str, np.ndarray]:
    """{id: position (3,) float64} of loaded objects (what the envmap nodes need)."""
    return {o["id"]: np.asarray(o["position"], np.float64) for o in objects}


def objects_file_problem(path: str) -> str | None:
    """A param check: '' (none) or a file :func:`load_objects` reads without error."""
    return file_load_problem(path, load_objects)
