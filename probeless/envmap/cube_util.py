"""Helpers of the cubemap renderer (:mod:`probeless.envmap.cubemap`, which re-exports them): a UV sphere, colour
checks, the per-face buckets of a point cloud and the box mip chain of a cubemap."""

from __future__ import annotations

import numpy as np

from probeless.errors import ProbelessError


def unit_sphere(rings: int = 16, segments: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) f32, triangles (T, 3) i32) of a UV sphere of radius 1."""
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    t, p = np.meshgrid(th, ph, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    i, j = np.mgrid[0:rings, 0:segments]
    a = (i * (segments + 1) + j).ravel()
    b, c, d = a + segments + 1, a + 1, a + segments + 2
    return v.astype("f4"), np.concatenate([np.stack([a, b, c], 1), np.stack([c, b, d], 1)]).astype("i4")


def linear_radiance(values: np.ndarray, what: str) -> np.ndarray:
    """float32 copy of HDR linear radiance (finite, >= 0; uint8 refused: it would be camera LDR codes)."""
    a = np.asarray(values)
    if a.dtype == np.uint8 or not np.issubdtype(a.dtype, np.number):
        raise ProbelessError(f"{what}: linear radiance must be floats, got dtype {a.dtype}")
    a = a.astype("f4")
    if not np.isfinite(a).all() or (a < 0).any():
        raise ProbelessError(f"{what}: linear radiance must be finite and >= 0")
    return a


def ldr_colors(colors: np.ndarray, what: str) -> np.ndarray:
    """(N, 3) float32 camera LDR 0..1 from uint8 0..255 or float 0..1 colours."""
    c = np.asarray(colors)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ProbelessError(f"{what}: colours must be (N, 3), got {c.shape}")
    return c.astype("f4") / 255.0 if c.dtype == np.uint8 else c.astype("f4")


def face_buckets(points: np.ndarray, position: np.ndarray, margin: float = 0.05) -> list[np.ndarray]:
    """Indices of the points each cube face can see (int32 per face), faces in cube order.

    A point goes to every face whose 90-degree frustum, widened by ``margin`` (tan units), holds it,
    so splats straddling a seam are drawn on both sides. Drawing each face's bucket instead of all
    points six times cuts the vertex work about six-fold.
    """
    d = np.asarray(points, np.float32) - np.asarray(position, np.float32)
    a = np.abs(d)
    out = []
    for axis in range(3):
        others = [k for k in range(3) if k != axis]
        side = np.maximum(a[:, others[0]], a[:, others[1]])
        for sign in (1.0, -1.0):
            forward = sign * d[:, axis]
            out.append(np.flatnonzero((forward > 0) & (side <= forward * (1.0 + margin))).astype("i4"))
    return out


def prefilter(faces: np.ndarray, levels: int) -> list[tuple[float, np.ndarray]]:
    """Mip chain of cubemap ``faces`` (6, S, S, C): [(roughness = i / (levels - 1), faces of side S >> i)].

    Each level is the 2x2 box average of the previous one (the paper samples coarser mip levels for
    rough metals). Level 0 is ``faces`` itself.
    """
    f = np.asarray(faces, np.float32)
    size = f.shape[1]
    if levels < 1 or size >> (levels - 1) < 1 or size % (1 << (levels - 1)):
        raise ProbelessError(f"prefilter: {levels} levels do not divide a {size}-texel face")
    out = [(0.0, f)]
    for i in range(1, levels):
        s = f.shape[1] // 2
        f = f.reshape(6, s, 2, s, 2, -1).mean(axis=(2, 4))
        out.append((i / (levels - 1), f))
    return out
