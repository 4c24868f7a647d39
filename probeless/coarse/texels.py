"""Atlas texel -> world position and surface, and the coarse model's triangle mesh (same mapping)."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from matplotlib.path import Path

from probeless.coarse.atlas import AtlasLayout, AtlasSurface
from probeless.scene.tessellate import triangulate


@dataclass(frozen=True)
class TexelMap:
    """Per-texel geometry of an atlas (arrays are atlas-sized, row-major like the image)."""

    position: np.ndarray   # (H, W, 3) float32 texel centre [m, world]; 0 where surface == -1
    normal: np.ndarray     # (H, W, 3) float32 inward unit normal [world]; 0 where surface == -1
    surface: np.ndarray    # (H, W) int16 index into layout.surfaces; -1 = no surface (gap)
    core: np.ndarray       # (H, W) bool: the texel centre lies on the surface itself (not padding/outside)

    @property
    def valid(self) -> np.ndarray:
        """(H, W) bool: the texel belongs to a surface (core, padding ring or floor rim): it gets texture."""
        return self.surface >= 0


def _surface_grid(layout: AtlasLayout, s: AtlasSurface, pad: int):
    """Columns, rows and (h, w, 3) positions of ``s``'s rectangle grown by ``pad``, clamped onto the surface."""
    x0, y0, w, h = s.rect
    cols = np.arange(max(0, x0 - pad), min(layout.width, x0 + w + pad))
    rows = np.arange(max(0, y0 - pad), min(layout.height, y0 + h + pad))
    d = layout.texels_per_m
    su = (cols - x0 + 0.5) / d
    sv = (rows - y0 + 0.5) / d
    inside = ((su >= 0) & (su <= s.size_m[0]))[None, :] & ((sv >= 0) & (sv <= s.size_m[1]))[:, None]
    su, sv = np.clip(su, 0, s.size_m[0]), np.clip(sv, 0, s.size_m[1])
    pos = s.origin + su[None, :, None] * s.u_axis + sv[:, None, None] * s.v_axis
    return cols, rows, pos, inside


def _ring(rect: tuple[int, int, int, int], cols: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(rows, cols) Chebyshev distance in texels from the rectangle (0 inside it)."""
    x0, y0, w, h = rect
    dx = np.maximum(np.maximum(x0 - cols, cols - (x0 + w - 1)), 0)
    dy = np.maximum(np.maximum(y0 - rows, rows - (y0 + h - 1)), 0)
    return np.maximum(dy[:, None], dx[None, :])


def texel_map(layout: AtlasLayout, *, pad: int | None = None) -> TexelMap:
    """World position, inward normal and surface of every atlas texel.

    Wall rectangles and their ``pad``-texel ring (default 2) map onto the wall (clamped at its
    ends), so bilinear lookups near an edge never read a gap. Floor and ceiling texels count when
    their centre is inside the floorplan or next to a texel that is (a one-texel rim). A ring never
    takes a texel of another surface's rectangle; where rings meet in a narrow gap, each texel goes
    to the nearest rectangle.
    """
    pad = 2 if pad is None else pad
    H, W = layout.height, layout.width
    position = np.zeros((H, W, 3), np.float32)
    normal = np.zeros((H, W, 3), np.float32)
    surface = np.full((H, W), -1, np.int16)
    core = np.zeros((H, W), bool)
    grids = []
    for s in layout.surfaces:
        cols, rows, pos, inside = _surface_grid(layout, s, pad)
        keep = np.ones(inside.shape, bool)
        if s.kind != "wall":  # unclamped, so rim texels sit just outside the room rather than on its bounding box
            d = layout.texels_per_m
            cu, cv = (cols - s.rect[0] + 0.5) / d, (rows - s.rect[1] + 0.5) / d
            pos = s.origin + cu[None, :, None] * s.u_axis + cv[:, None, None] * s.v_axis
            xy = pos[..., :2].reshape(-1, 2)
            within = Path(layout.floorplan).contains_points(xy).reshape(inside.shape)
            inside = inside & within
            keep = cv2.dilate(within.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        grids.append((cols, rows, pos, inside & keep, keep))
    for k, (cols, rows, pos, inside, keep) in enumerate(grids):  # rectangles first: rings never take their texels
        x0, y0, w, h = layout.surfaces[k].rect
        sub = (slice(y0 - rows[0], y0 - rows[0] + h), slice(x0 - cols[0], x0 - cols[0] + w))
        rect = (slice(y0, y0 + h), slice(x0, x0 + w))
        write = keep[sub]
        position[rect][write] = pos[sub][write]
        normal[rect][write] = layout.surfaces[k].normal
        surface[rect][write] = k
        core[rect] |= inside[sub]
    rings = []
    for k, (cols, rows, pos, inside, keep) in enumerate(grids):
        ring = _ring(layout.surfaces[k].rect, cols, rows)
        rr, cc = np.nonzero((ring > 0) & keep)
        rings.append((rr, cc, ring[rr, cc]))
    for level in range(1, pad + 1):  # then rings outward, into texels still free: the nearest rectangle wins
        for k, (rr, cc, lv) in enumerate(rings):
            cols, rows, pos, inside, _ = grids[k]
            r, c = rr[lv == level], cc[lv == level]
            free = surface[rows[r], cols[c]] < 0
            r, c = r[free], c[free]
            position[rows[r], cols[c]] = pos[r, c]
            normal[rows[r], cols[c]] = layout.surfaces[k].normal
            surface[rows[r], cols[c]] = k
            core[rows[r], cols[c]] |= inside[r, c]
    return TexelMap(position, normal, surface, core)


def _uv(layout: AtlasLayout, s: AtlasSurface, su: np.ndarray, sv: np.ndarray) -> np.ndarray:
    """OpenGL texture coordinates (u right, v up) of surface coordinates (su, sv) [m]."""
    d = layout.texels_per_m
    x = s.rect[0] + su * d
    y = s.rect[1] + sv * d
    return np.stack([x / layout.width, 1.0 - y / layout.height], axis=-1)


def coarse_mesh(layout: AtlasLayout) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The prism as (vertices (V, 3) float32, triangles (T, 3) int32, uvs (V, 2) float32, surface per triangle (T,)).

    Triangles are counter-clockwise seen from inside the room; uvs address ``layout``'s atlas.
    """
    verts, uvs, tris, tri_surface = [], [], [], []
    for k, s in enumerate(layout.surfaces):
        base = sum(len(v) for v in verts)
        if s.kind == "wall":
            su = np.array([0.0, s.size_m[0], s.size_m[0], 0.0])
            sv = np.array([0.0, 0.0, s.size_m[1], s.size_m[1]])
            local = np.array([[0, 1, 2], [0, 2, 3]])
        else:
            poly = layout.floorplan
            su = poly[:, 0] - s.origin[0]
            sv = s.origin[1] - poly[:, 1]
            local = triangulate(poly)
        p = s.origin + su[:, None] * s.u_axis + sv[:, None] * s.v_axis
        a, b, c = (p[local[:, i]] for i in range(3))
        facing = np.einsum("ij,j->i", np.cross(b - a, c - a), s.normal)
        local = np.where((facing < 0)[:, None], local[:, [0, 2, 1]], local)
        verts.append(p)
        uvs.append(_uv(layout, s, su, sv))
        tris.append(local + base)
        tri_surface.append(np.full(len(local), k))
    return (np.concatenate(verts).astype(np.float32), np.concatenate(tris).astype(np.int32),
            np.concatenate(uvs).astype(np.float32), np.concatenate(tri_surface).astype(np.int16))
