"""Minimal Wavefront OBJ reading (positions and faces) and mesh placement for scene furniture."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from probeless.errors import SceneError


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float64, triangles (T, 3) int64) of an OBJ file; polygons are fanned.

    Only ``v`` and ``f`` lines are used (``f a/b/c`` forms and negative indices accepted).
    """
    try:
        lines = Path(path).read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read mesh: {exc}") from None
    verts: list[list[float]] = []
    tris: list[tuple[int, int, int]] = []
    for number, line in enumerate(lines, 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
                if len(verts[-1]) != 3:
                    raise ValueError("a vertex needs 3 coordinates")
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                if len(idx) < 3:
                    raise ValueError("a face needs at least 3 vertices")
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                tris.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
        except ValueError as exc:
            raise SceneError(f"{path}:{number}: malformed OBJ line {line.strip()!r}: {exc}") from None
    v, f = np.array(verts, np.float64).reshape(-1, 3), np.array(tris, np.int64).reshape(-1, 3)
    if len(f) == 0:
        raise SceneError(f"{path}: mesh has no faces")
    if f.min() < 0 or f.max() >= len(v):
        raise SceneError(f"{path}: face index out of range (mesh has {len(v)} vertices)")
    if not np.all(np.isfinite(v)):
        raise SceneError(f"{path}: vertex coordinates contain NaN or inf")
    return v, f


def place_mesh(vertices: np.ndarray, up: str, scale: float, yaw_deg: float, position: np.ndarray) -> np.ndarray:
    """World positions of mesh vertices: make ``up`` the world z axis, scale, yaw about z, translate."""
    v = vertices * scale
    if up == "y":  # file (x, y, z) with y up -> world (x, -z, y): a right-handed rotation about x by +90 deg
        v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return v @ R.T + position


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted, normalised per-vertex normals (V, 3) from counter-clockwise triangles."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    face = np.cross(b - a, c - a)
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, triangles[:, k], face)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.where(length > 0, length, 1.0)
