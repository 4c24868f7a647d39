"""Virtual objects of the environment-map nodes: positions from params and poses, and their nets.

Shared by ``cubemap_renderer`` and ``baseline_envmap`` (they take the same ``objects_file``,
``object_ids`` / ``object_positions`` params and ``object_poses`` input, so the two swap by one ``node:`` line).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from probeless.errors import ParamError
from probeless.messages.geometry import PoseStamped
from probeless.scene.objects_file import load_objects, object_positions
from probeless.scene.preview import cube_net, write_png


def object_ids_problem(ids: tuple) -> str | None:
    """The ``object_ids`` param's rule (a param check): unique, non-empty ids without '/'."""
    for i, oid in enumerate(ids):
        if not oid or "/" in oid or oid in ids[:i]:
            return f"object_ids[{i}]: must be unique, non-empty and without '/', got {oid!r}"
    return None


def object_positions_problem(positions: tuple, params) -> str | None:
    """The ``object_positions`` param's rule (a param check): one [x, y, z] of finite numbers per object id."""
    ids = params.object_ids
    if len(ids) != len(positions):
        return f"{len(ids)} object_ids but {len(positions)} object_positions: need one [x, y, z] per id"
    for i, pos in enumerate(positions):
        xyz = np.asarray(pos, np.float64)
        if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
            return f"object_positions[{i}]: need 3 finite numbers [m, world], got {list(pos)!r}"
    return None


def parse_objects(ids: tuple, positions: tuple, node_id: str) -> dict[str, np.ndarray]:
    """{id: position (3,) float64} of the ``object_ids`` / ``object_positions`` params (as the cubemap renderer's).

    The params are checked when the graph loads (the two rules above); ParamError here too for direct callers.
    """
    for key, problem in (("object_ids", object_ids_problem(ids)),
                         ("object_positions", object_positions_problem(positions, SimpleNamespace(object_ids=ids)))):
        if problem:
            raise ParamError(problem, node_id=node_id, key=key)
    return {oid: np.asarray(pos, np.float64) for oid, pos in zip(ids, positions)}


def node_objects(objects_file: str, ids: tuple, positions: tuple, node_id: str) -> dict[str, np.ndarray]:
    """{id: position} of an envmap node: the ``objects_file``'s objects, then the params' (ids must not repeat)."""
    objects = object_positions(load_objects(objects_file)) if objects_file else {}
    for oid, pos in parse_objects(ids, positions, node_id).items():
        if oid in objects:
            raise ParamError(f"object {oid!r} is in objects_file and object_ids", node_id=node_id, key="object_ids")
        objects[oid] = pos
    return objects


def move_object(objects: dict[str, np.ndarray], msg: PoseStamped, counts: Counter) -> None:
    """Move (or add) the object ``msg.child_frame_id`` to the pose's position; a non-finite pose is counted."""
    T = msg.target_from_source
    if np.isfinite(T).all():
        objects[msg.child_frame_id] = T[:3, 3].astype(np.float64)
    else:
        counts["bad_object_pose"] += 1


def write_nets(faces_by_id: dict[str, np.ndarray], out_dir: str) -> None:
    """``cubemap_net_<id>.png`` (horizontal cross, z up) of each object's LDR faces."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for oid, faces in faces_by_id.items():
        write_png(out / f"cubemap_net_{oid}.png", (np.clip(cube_net(faces), 0, 1) * 255 + 0.5).astype(np.uint8))
