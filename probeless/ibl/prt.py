"""Diffuse precomputed radiance transfer (Sloan et al. 2002), computed at load time by ray casting.

The transfer vector of a point with normal ``n`` is ``T_k = integral V(w) max(0, n . w) Y_k(w) dw``
(``V`` = 1 where the ray leaves unblocked), estimated over ``n_dirs`` Fibonacci-sphere directions
of equal solid angle ``4 pi / n_dirs``. Irradiance under SH radiance ``L`` is then ``T . L``.
With ``V = 1`` it approaches the cosine-lobe convolution of :func:`probeless.envmap.sh.irradiance_from_sh`.
"""

from __future__ import annotations

import numpy as np

from probeless.envmap.sh import sh_basis
from probeless.ibl.mesh_io import PlacedMesh


def fibonacci_directions(n: int) -> np.ndarray:
    """(n, 3) unit directions spread evenly over the sphere (each stands for 4 pi / n sr)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5 ** 0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _occluded(mesh: PlacedMesh, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(P, D) bool: does the ray from origin p along direction d hit the mesh?"""
    import open3d as o3d  # slow import: only when PRT is asked for

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(mesh.vertices.astype(np.float32), mesh.triangles.astype(np.uint32))
    rays = np.concatenate(np.broadcast_arrays(origins[:, None, :], dirs[None, :, :]), axis=-1)
    hit = scene.test_occlusions(o3d.core.Tensor(rays.reshape(-1, 6).astype(np.float32)))
    return hit.numpy().reshape(len(origins), len(dirs))


def transfer_vectors(mesh: PlacedMesh, points: np.ndarray, normals: np.ndarray, *, bands: int = 5,
                     n_dirs: int = 512, offset: float | None = None) -> np.ndarray:
    """(P, bands^2) shadowed diffuse transfer of ``points`` (P, 3) with ``normals`` (P, 3) against ``mesh``.

    Rays start ``offset`` (default 1e-3 of the mesh radius) along the normal to skip the surface itself.
    """
    dirs = fibonacci_directions(n_dirs)
    eps = 1e-3 * mesh.radius if offset is None else offset
    cos = np.clip(normals @ dirs.T, 0.0, None)                     # (P, D)
    basis = sh_basis(dirs, bands) * (4 * np.pi / n_dirs)           # (D, K)
    out = np.empty((len(points), bands * bands))
    for s in range(0, len(points), 4096):                          # bounded memory for big meshes
        sl = slice(s, s + 4096)
        visible = ~_occluded(mesh, points[sl] + eps * normals[sl], dirs)
        out[sl] = (cos[sl] * visible) @ basis
    return out


def unshadowed_transfer(normals: np.ndarray, *, bands: int = 5, n_dirs: int = 512) -> np.ndarray:
    """(P, bands^2) transfer with no occlusion, by the same direction set (the ratio's denominator)."""
    dirs = fibonacci_directions(n_dirs)
    return np.clip(normals @ dirs.T, 0.0, None) @ (sh_basis(dirs, bands) * (4 * np.pi / n_dirs))


def floor_grid(centre_xy, half_extent: float, z: float, n: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n*n, 3), triangles) of a square grid at height ``z`` centred on ``centre_xy``."""
    t = np.linspace(-half_extent, half_extent, n)
    x, y = np.meshgrid(t + centre_xy[0], t + centre_xy[1], indexing="xy")
    verts = np.stack([x, y, np.full_like(x, z)], axis=-1).reshape(-1, 3)
    r, c = np.mgrid[0:n - 1, 0:n - 1]
    a = (r * n + c).ravel()
    tris = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    return verts, tris.astype(np.int64)


def edge_falloff(verts: np.ndarray, centre_xy, half_extent: float, width: float = 0.25) -> np.ndarray:
    """(V,) weight 1 inside the grid, easing to 0 over the outer ``width`` fraction (no visible seam)."""
    d = np.abs(verts[:, :2] - np.asarray(centre_xy)[None]).max(axis=1) / half_extent
    t = np.clip((1.0 - d) / width, 0.0, 1.0)
    return t * t * (3 - 2 * t)
