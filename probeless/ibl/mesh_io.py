"""Virtual-object meshes: OBJ / PLY loading (with texture coordinates: :func:`load_mesh_uv`), a UV sphere, and
placement in the world.

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
    uvs: np.ndarray | None = None  # (V, 2) float64 texture coordinates (u right, v up: OBJ convention) or None

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


def uv_sphere_uv(radius: float = 1.0, rings: int = 48, segments: int = 96
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices, triangles, uvs) of a UV sphere with longitude / latitude texture coordinates.

    u = longitude / 2 pi (0 at +x, growing towards +y), v = 1 at the north pole (+z) down to 0 at the south pole.
    Vertices are a (rings + 1) x (segments + 1) grid: the seam column and the poles are repeated so each vertex has
    one UV (at the poles one vertex per segment, every one at the pole).
    """
    theta = np.linspace(0, np.pi, rings + 1)
    phi = np.linspace(0, 2 * np.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    verts = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3) * radius
    verts[:segments + 1] = [0.0, 0.0, radius]  # exact poles (sin(pi) is not 0 in floating point)
    verts[-(segments + 1):] = [0.0, 0.0, -radius]
    grid = verts.reshape(rings + 1, segments + 1, 3)
    grid[:, -1] = grid[:, 0]  # the seam column at exactly the first column's positions (welded normals)
    uvs = np.stack([p / (2 * np.pi), 1 - t / np.pi], axis=-1).reshape(-1, 2)
    r, s = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a, b = r * (segments + 1) + s, r * (segments + 1) + s + 1
    c, d = a + segments + 1, b + segments + 1
    upper = np.stack([a, c, b], axis=-1)[1:]   # the top row's (a, c, b) has both a and b at the pole
    lower = np.stack([b, c, d], axis=-1)[:-1]  # the bottom row's (b, c, d) has both c and d at the pole
    return verts, np.vstack([upper.reshape(-1, 3), lower.reshape(-1, 3)]).astype(np.int64), uvs


def load_mesh_uv(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(vertices (V, 3), triangles (T, 3), uvs (V, 2) or None) of an ``.obj`` file, a ``.ply`` or ``"sphere"``.

    OBJ faces index positions and texture coordinates (``f v/vt ...``) separately; each distinct (v, vt) pair
    becomes one output vertex, so a position on a UV seam is repeated (positions no face uses are dropped). UVs are
    None for a PLY or an OBJ any face of which has no ``vt`` index (then the result is :func:`load_mesh`'s).
    """
    if str(path) == "sphere":
        return uv_sphere_uv()
    p = Path(path)
    if not p.is_file() or p.suffix.lower() != ".obj":
        return (*load_mesh(p), None)
    v, f = load_mesh(p)  # positions and faces, checked
    texcoords, vt = _read_obj_texcoords(p)
    if vt is None or len(texcoords) == 0:
        return v, f, None
    if vt.min() < 0 or vt.max() >= len(texcoords):
        raise SceneError(f"{p}: texture coordinate index out of range (mesh has {len(texcoords)} vt lines)")
    pairs, inverse = np.unique(np.stack([f.reshape(-1), vt], axis=-1), axis=0, return_inverse=True)
    return v[pairs[:, 0]], inverse.reshape(-1, 3).astype(np.int64), texcoords[pairs[:, 1]]


def _read_obj_texcoords(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(texcoords (N, 2), the 0-based vt index of every corner of the fanned triangles (3T,), in the order of
    :func:`~probeless.scene.obj.read_obj`'s triangles, or None when a face has no vt index) of an OBJ file."""
    texcoords: list[list[float]] = []
    corners: list[int] = []
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read mesh: {exc}") from None
    for number, line in enumerate(lines, 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "vt":
                texcoords.append([float(parts[1]), float(parts[2]) if len(parts) > 2 else 0.0])
            elif parts[0] == "f":
                fields = [c.split("/") for c in parts[1:]]
                if any(len(c) < 2 or not c[1] for c in fields):
                    return np.zeros((0, 2)), None
                idx = [int(c[1]) for c in fields]
                idx = [t - 1 if t > 0 else len(texcoords) + t for t in idx]
                for k in range(1, len(idx) - 1):
                    corners += [idx[0], idx[k], idx[k + 1]]
        except (ValueError, IndexError) as exc:
            raise SceneError(f"{path}:{number}: malformed OBJ line {line.strip()!r}: {exc}") from None
    uv = np.array(texcoords, np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(uv)):
        raise SceneError(f"{path}: texture coordinates contain NaN or inf")
    return uv, np.array(corners, np.int64)


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
          scale: float = 1.0, yaw_deg: float = 0.0, up: str = "y", anchor: str = "center",
          uvs: np.ndarray | None = None) -> PlacedMesh:
    """The mesh centred, scaled, turned z-up, yawed and moved to ``position`` (see module doc).

    ``uvs`` (V, 2), one per vertex, are carried through; with them, normals are computed over the mesh with
    coincident vertices (UV seams) merged, so shading has no seams.
    """
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
    if uvs is None:
        return PlacedMesh(world, tris, vertex_normals(world, tris), offset)
    uvs = np.asarray(uvs, np.float64)
    if uvs.shape != (len(world), 2):
        raise SceneError(f"mesh uvs must be ({len(world)}, 2), one per vertex, got {uvs.shape}")
    return PlacedMesh(world, tris, welded_normals(world, tris), offset, uvs)


def welded_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """:func:`~probeless.scene.obj.vertex_normals` of the mesh whose vertices at the same position are merged."""
    unique, index = np.unique(vertices, axis=0, return_inverse=True)
    index = index.reshape(-1)
    return vertex_normals(unique, index[triangles])[index]
