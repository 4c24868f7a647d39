"""Cubemap geometry: texel directions, their inverse, texel solid angles, nearest lookup, face cameras.

Convention (the world frame *is* the cube frame, z-up; :mod:`probeless.messages.lighting`): face
``i`` is uploaded unchanged to ``GL_TEXTURE_CUBE_MAP_POSITIVE_X + i`` and sampled with the
world-frame direction unchanged. Face order is OpenGL's: +X, -X, +Y, -Y, +Z (up, the ceiling),
-Z (down, the floor). Texel ``[face, row, col]`` has ``s = (col + 0.5) / size`` and
``t = (row + 0.5) / size`` and, with ``a = 2s - 1``, ``b = 2t - 1``, looks along the
(unnormalised) world direction of the OpenGL table::

    +X: ( 1, -b, -a)   -X: (-1, -b,  a)   +Y: ( a,  1,  b)
    -Y: ( a, -1, -b)   +Z: ( a, -b,  1)   -Z: (-a, -b, -1)
"""

from __future__ import annotations

import numpy as np

from probeless.geom.projection import clip_from_camera, view_from_world

CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")

# Rows (U, V, F) of each cube face frame, face order +X, -X, +Y, -Y, +Z, -Z: texel (a, b) of a
# face looks along F + a U + b V (the OpenGL table above).
CUBE_FACE_FRAMES = np.array([
    [(0, 0, -1), (0, -1, 0), (1, 0, 0)],
    [(0, 0, 1), (0, -1, 0), (-1, 0, 0)],
    [(1, 0, 0), (0, 0, 1), (0, 1, 0)],
    [(1, 0, 0), (0, 0, -1), (0, -1, 0)],
    [(1, 0, 0), (0, -1, 0), (0, 0, 1)],
    [(-1, 0, 0), (0, -1, 0), (0, 0, -1)],
], dtype=np.float64)


def texel_direction(face: int, row: np.ndarray, col: np.ndarray, size: int) -> np.ndarray:
    """Unit world direction(s) (..., 3) float64 through the centre of texel (row, col) of a cube face."""
    a = 2.0 * (np.asarray(col, dtype=np.float64) + 0.5) / size - 1.0
    b = 2.0 * (np.asarray(row, dtype=np.float64) + 0.5) / size - 1.0
    one = np.ones_like(a + b)
    d = [(one, -b, -a), (-one, -b, a), (a, one, b), (a, -one, -b), (a, -b, one), (-a, -b, -one)][face]
    v = np.stack(np.broadcast_arrays(*d), axis=-1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def cube_directions(size: int) -> np.ndarray:
    """(6, S, S, 3) float64 unit world direction of every cube texel centre; ``.reshape(-1, 3)`` lists them
    in [face, row, col] order."""
    r, c = np.mgrid[0:size, 0:size]
    return np.stack([texel_direction(f, r, c, size) for f in range(6)])


def cube_solid_angles(size: int) -> np.ndarray:
    """(6, S, S) float64 exact solid angle of every cube texel [sr]; they sum to 4 pi.

    The texel [a0, a1] x [b0, b1] on a face plane at distance 1 subtends
    ``F(a1, b1) - F(a0, b1) - F(a1, b0) + F(a0, b0)`` with ``F(a, b) = atan2(a b, sqrt(a^2 + b^2 + 1))``
    (the integral of the area element ``dA / (1 + a^2 + b^2)^(3/2)`` from the face centre).
    """
    edges = np.linspace(-1.0, 1.0, size + 1)
    a, b = np.meshgrid(edges, edges, indexing="xy")  # b varies along rows
    f = np.arctan2(a * b, np.sqrt(a * a + b * b + 1.0))
    omega = f[1:, 1:] - f[:-1, 1:] - f[1:, :-1] + f[:-1, :-1]
    return np.broadcast_to(omega, (6, size, size)).copy()


def texel_from_direction(dirs: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`texel_direction`: (face, row, col) float texel coordinates of world directions (..., 3).

    ``row``/``col`` are continuous (texel centres at integers); round them for a nearest lookup.
    """
    d = np.asarray(dirs, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    face = np.where((ax >= ay) & (ax >= az), np.where(x > 0, 0, 1),
                    np.where(ay >= az, np.where(y > 0, 2, 3), np.where(z > 0, 4, 5)))
    major = np.maximum(np.maximum(ax, ay), np.maximum(az, 1e-300))
    # (a, b) per face from the OpenGL table, divided by the major axis
    a = np.choose(face, [-z, z, x, x, x, -x]) / major
    b = np.choose(face, [-y, -y, z, -z, -y, -y]) / major
    col = (a + 1.0) * 0.5 * size - 0.5
    row = (b + 1.0) * 0.5 * size - 0.5
    return face, row, col


def sample_cubemap(faces: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Nearest-texel lookup of cubemap ``faces`` (6, S, S, C) along world directions (..., 3) -> (..., C)."""
    size = faces.shape[1]
    face, row, col = texel_from_direction(dirs, size)
    r = np.clip(np.round(row).astype(np.int64), 0, size - 1)
    c = np.clip(np.round(col).astype(np.int64), 0, size - 1)
    return faces[face, r, c]


def cube_face_clip_from_world(position: np.ndarray, size: int, near: float, far: float) -> list[np.ndarray]:
    """Six 90-degree clip_from_world matrices whose framebuffer texel (row, col) is cube texel [face, row, col]."""
    half = size / 2.0
    K = np.array([[half, 0, half - 0.5], [0, half, half - 0.5], [0, 0, 1]])
    proj = clip_from_camera(K, size, size, near, far)
    return [proj @ view_from_world(CUBE_FACE_FRAMES[f], position) for f in range(6)]
