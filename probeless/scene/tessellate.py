"""Triangle soups for scene parts: polygon triangulation (ear clipping), quads and boxes.

Soups are ``(positions (3T, 3), normals (3T, 3), uvs (3T, 2))``, counter-clockwise seen from the
side the normals point to.
"""

from __future__ import annotations

import numpy as np

from probeless.errors import SceneError
from probeless.geom.polygon import signed_area


def _cross2(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _in_triangle(p, a, b, c) -> bool:
    return _cross2(a, b, p) >= 0 and _cross2(b, c, p) >= 0 and _cross2(c, a, p) >= 0


def triangulate(poly: np.ndarray) -> np.ndarray:
    """(N - 2, 3) vertex indices triangulating a simple counter-clockwise polygon (ear clipping)."""
    if signed_area(poly) <= 0:
        raise SceneError("triangulate: polygon must be counter-clockwise")
    remaining = list(range(len(poly)))
    tris = []
    while len(remaining) > 3:
        for k in range(len(remaining)):
            i, j, l = remaining[k - 1], remaining[k], remaining[(k + 1) % len(remaining)]
            a, b, c = poly[i], poly[j], poly[l]
            if _cross2(a, b, c) <= 1e-12:
                continue  # reflex or degenerate corner: not an ear
            others = (poly[m] for m in remaining if m not in (i, j, l))
            if any(_in_triangle(p, a, b, c) for p in others):
                continue
            tris.append((i, j, l))
            remaining.pop(k)
            break
        else:
            raise SceneError("triangulate: no ear found (polygon is not simple)")
    tris.append(tuple(remaining))
    return np.array(tris, np.int64)


def quad(p0: np.ndarray, edge_u: np.ndarray, edge_v: np.ndarray, normal: np.ndarray,
         uv0: tuple[float, float] = (0.0, 0.0), uv_size: tuple[float, float] | None = None):
    """Two triangles covering the parallelogram ``p0 + a edge_u + b edge_v`` (a, b in [0, 1]) facing ``normal``."""
    if uv_size is None:
        uv_size = (float(np.linalg.norm(edge_u)), float(np.linalg.norm(edge_v)))
    corners = np.array([p0, p0 + edge_u, p0 + edge_u + edge_v, p0 + edge_v], np.float64)
    uvs = np.array(uv0) + np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * np.array(uv_size)
    order = [0, 1, 2, 0, 2, 3] if np.dot(np.cross(edge_u, edge_v), normal) > 0 else [0, 2, 1, 0, 3, 2]
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    return corners[order], np.tile(n, (6, 1)), uvs[order].astype(np.float64)


def box_faces(center: np.ndarray, size: np.ndarray):
    """The 6 outward-facing faces of an axis-aligned box; uvs in metres."""
    lo = center - size / 2
    parts = []
    for axis in range(3):
        u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
        eu, ev = np.zeros(3), np.zeros(3)
        eu[u_axis], ev[v_axis] = size[u_axis], size[v_axis]
        for side in (0, 1):
            p0 = lo.copy()
            p0[axis] += side * size[axis]
            normal = np.zeros(3)
            normal[axis] = 1.0 if side else -1.0
            parts.append(quad(p0, eu, ev, normal))
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))
