"""Virtual-object meshes: OBJ / PLY loading, a UV sphere, and placement in the world.

A placed mesh is centred on its bounding-box centre, scaled (to a bounding-sphere ``radius`` or
by a plain ``scale``), turned so the file's ``up`` axis is world z, yawed about z and moved so
``position`` is its centre (``anchor="center"``) or the centre of its bottom (``anchor="bottom"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from probeless.errors import SceneError
from probeless.scene.obj import place_mesh, read_obj, vertex_normals


@dataclass(frozen=True)
class PlacedMesh:
    """Triangles in world coordinates with per-vertex unit normals."""

    vertices: np.ndarray   # (V, 3) float64 world [m]
    triangles: np.ndarray  # (T, 3) int64, counter-clockwise seen from outside
    normals: np.ndarray    # (V, 3) float64 unit, world
    centre: np.ndarray     # (3,) world position of the file's bounding-box centre [m]

    @property
    def radius(self) -> float:
        """Bounding-sphere radius about :attr:`centre` [m]."""
        return float(np.linalg.norm(self.vertices - self.centre, axis=1).max())


def uv_sphere(radius: float = 1.0, rings: int = 48, segments: int = 96) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3), triangles (T, 3)) of a UV sphere about the origin, z = pole axis, CCW outside."""
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    verts = np.vstack([[0, 0, 1], ring, [0, 0, -1]]) * radius
    south = len(verts) - 1
    def idx(r, s):
        return 1 + r * segments + (s % segments)
    tris = [(0, idx(0, s), idx(0, s + 1)) for s in range(segments)]
    for r in range(rings - 2):
        for s in range(segments):
            a, b, c, d = idx(r, s), idx(r, s + 1), idx(r + 1, s), idx(r + 1, s + 1)
            tris += [(a, c, b), (b, c, d)]
    tris += [(idx(rings - 2, s), south, idx(rings - 2, s + 1)) for s in range(segments)]
    return verts, np.array(tris, np.int64)


def load_mesh(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float64, triangles (T, 3) int64) of an ``.obj`` or ``.ply`` file (or ``"sphere"``)."""
    if str(path) == "sphere":
        return uv_sphere()
    p = Path(path)
    if not p.is_file():
        raise SceneError(f"{p}: mesh file not found")
    suffix = p.suffix.lower()
    if suffix == ".obj":
        return read_obj(p)
    if suffix == ".ply":
        import open3d as o3d  # slow import: only when a PLY is asked for

        mesh = o3d.io.read_triangle_mesh(str(p))
        v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.triangles, np.int64)
        if len(f) == 0:
            raise SceneError(f"{p}: PLY has no triangles (point clouds are not meshes)")
        if not np.all(np.isfinite(v)):
            raise SceneError(f"{p}: vertex coordinates contain NaN or inf")
        return v, f
    raise SceneError(f"{p}: unknown mesh format {suffix!r} (expected .obj or .ply)")


def place(vertices: np.ndarray, triangles: np.ndarray, position, *, radius: float | None = None,
          scale: float = 1.0, yaw_deg: float = 0.0, up: str = "y", anchor: str = "center") -> PlacedMesh:
    """The mesh centred, scaled, turned z-up, yawed and moved to ``position`` (see module doc)."""
    if up not in ("y", "z"):
        raise SceneError(f"mesh up axis must be 'y' or 'z', got {up!r}")
    if anchor not in ("center", "bottom"):
        raise SceneError(f"mesh anchor must be 'center' or 'bottom', got {anchor!r}")
    v = np.asarray(vertices, np.float64)
    v = v - (v.min(axis=0) + v.max(axis=0)) / 2
    extent = float(np.linalg.norm(v, axis=1).max())
    if not extent > 0:
        raise SceneError("mesh is degenerate (all vertices coincide)")
    s = radius / extent if radius is not None else scale
    if not (s > 0 and math.isfinite(s)):
        raise SceneError(f"mesh scale must be > 0, got radius={radius} scale={scale}")
    world = place_mesh(v, up, s, yaw_deg, np.zeros(3))
    offset = np.asarray(position, np.float64).copy()
    if anchor == "bottom":
        offset[2] -= world[:, 2].min()
    world = world + offset
    tris = np.asarray(triangles, np.int64)
    return PlacedMesh(world, tris, vertex_normals(world, tris), offset)
