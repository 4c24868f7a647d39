"""Coarse room model (paper §4.1): the right prism over a floorplan and its texture atlas layout.

Every surface (wall i, floor, ceiling) gets a rectangle in one atlas image at the same texel
density ``texels_per_m``. Atlas pixel (col c, row r) inside a surface's rectangle ``(x0, y0, w, h)``
lies at ``origin + u_axis * (c - x0 + 0.5) / d + v_axis * (r - y0 + 0.5) / d`` (d = texels per metre):

* wall i runs from floorplan vertex i to i + 1: origin = top of vertex i, u along the wall, v down;
* floor: origin = (x_min, y_max, 0), u = +x, v = -y (a top view, north up);
* ceiling: the same in x, y at z = ceiling height.

Rectangles are ``ceil(size * d)`` texels, so the last row/column may reach past the surface;
those texels' positions are clamped onto it. ``padding`` texels separate rectangles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from probeless.errors import GeometryError
from probeless.geom.floorplan import check_ceiling_height, check_floorplan

FLOOR, CEILING = "floor", "ceiling"
UNSEEN_GREY = 128 / 255  # camera LDR colour of never-observed texels: neutral grey (sRGB code 128), as in the paper


@dataclass(frozen=True)
class AtlasSurface:
    """One planar surface of the prism and its rectangle in the atlas."""

    name: str                 # "wall<i>" | "floor" | "ceiling"
    kind: str                 # "wall" | "floor" | "ceiling"
    origin: np.ndarray        # (3,) world point at the rectangle's top-left texel corner [m, world]
    u_axis: np.ndarray        # (3,) unit vector along atlas columns [world]
    v_axis: np.ndarray        # (3,) unit vector along atlas rows [world]
    normal: np.ndarray        # (3,) unit normal pointing into the room [world]
    size_m: tuple[float, float]  # extent along u, v [m]
    rect: tuple[int, int, int, int]  # (x0, y0, width, height) in the atlas [texels]


@dataclass(frozen=True)
class AtlasLayout:
    """Where every surface of the prism lives in a ``width`` x ``height`` atlas."""

    floorplan: np.ndarray     # (N, 2) counter-clockwise [m, world]
    ceiling_height: float     # [m]
    texels_per_m: float       # uniform texel density [texels / m]
    width: int                # atlas width [texels]
    height: int               # atlas height [texels]
    surfaces: tuple[AtlasSurface, ...]  # walls 0..N-1, then floor, then ceiling

    def surface(self, name: str) -> AtlasSurface:
        """The surface called ``name`` ("wall<i>", "floor", "ceiling")."""
        for s in self.surfaces:
            if s.name == name:
                return s
        raise KeyError(name)

    @property
    def walls(self) -> tuple[AtlasSurface, ...]:
        return tuple(s for s in self.surfaces if s.kind == "wall")


def _surfaces_m(poly: np.ndarray, h: float) -> list[tuple]:
    """(name, kind, origin, u, v, normal, size_m) for every surface, before packing."""
    out = []
    down = np.array([0.0, 0.0, -1.0])
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        length = float(np.linalg.norm(b - a))  # > 0: check_floorplan rejects coinciding vertices
        u = np.array([*(b - a) / length, 0.0])
        inward = np.array([-u[1], u[0], 0.0])  # left of a->b is inside a counter-clockwise polygon
        out.append((f"wall{i}", "wall", np.array([a[0], a[1], h]), u, down, inward, (length, h)))
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    size = (float(hi[0] - lo[0]), float(hi[1] - lo[1]))
    ex, ey = np.array([1.0, 0, 0]), np.array([0, -1.0, 0])
    out.append((FLOOR, FLOOR, np.array([lo[0], hi[1], 0.0]), ex, ey, np.array([0, 0, 1.0]), size))
    out.append((CEILING, CEILING, np.array([lo[0], hi[1], h]), ex, ey, np.array([0, 0, -1.0]), size))
    return out


def _shelf_pack(sizes: list[tuple[int, int]], width: int, padding: int) -> tuple[list[tuple[int, int]], int] | None:
    """Top-left corners packing ``sizes`` (w, h) into rows of ``width``, tallest first; None if one is too wide."""
    order = sorted(range(len(sizes)), key=lambda k: (-sizes[k][1], -sizes[k][0]))
    corners: list[tuple[int, int]] = [(0, 0)] * len(sizes)
    x = y = shelf_h = 0
    for k in order:
        w, h = sizes[k]
        if w + 2 * padding > width:
            return None
        if x + w + 2 * padding > width:
            x, y, shelf_h = 0, y + shelf_h, 0
        corners[k] = (x + padding, y + padding)
        x += w + 2 * padding
        shelf_h = max(shelf_h, h + 2 * padding)
    return corners, y + shelf_h


def layout_atlas(floorplan: np.ndarray, ceiling_height: float, texels_per_m: float, *,
                 width: int | None = None, padding: int = 2) -> AtlasLayout:
    """Pack the prism's surfaces at ``texels_per_m`` into an atlas ``width`` texels wide (default: ~square)."""
    poly = check_floorplan(floorplan)
    check_ceiling_height(ceiling_height)
    if not (math.isfinite(texels_per_m) and texels_per_m > 0):
        raise GeometryError(f"texels_per_m must be > 0, got {texels_per_m}")
    raw = _surfaces_m(poly, float(ceiling_height))
    sizes = [(max(1, math.ceil(s[6][0] * texels_per_m)), max(1, math.ceil(s[6][1] * texels_per_m))) for s in raw]
    if width is None:
        area = sum((w + 2 * padding) * (h + 2 * padding) for w, h in sizes)
        width = max(max(w for w, _ in sizes) + 2 * padding, math.ceil(math.sqrt(area * 1.15)))
    packed = _shelf_pack(sizes, width, padding)
    if packed is None:
        raise GeometryError(f"a surface is wider than the atlas ({width} texels) at {texels_per_m} texels/m")
    corners, height = packed
    surfaces = tuple(AtlasSurface(name, kind, origin, u, v, n, size_m, (x0, y0, w, h))
                     for (name, kind, origin, u, v, n, size_m), (x0, y0), (w, h) in zip(raw, corners, sizes))
    return AtlasLayout(poly, float(ceiling_height), float(texels_per_m), int(width), int(height), surfaces)


def fit_atlas(floorplan: np.ndarray, ceiling_height: float, size: int, *, padding: int = 2) -> AtlasLayout:
    """The densest layout that fits a ``size`` x ``size`` atlas (bisection on texels per metre)."""
    lo, hi = 1e-3, float(size)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        try:
            fits = layout_atlas(floorplan, ceiling_height, mid, width=size, padding=padding).height <= size
        except GeometryError as e:
            if "wider than the atlas" not in str(e):
                raise
            fits = False
        lo, hi = (mid, hi) if fits else (lo, mid)
    layout = layout_atlas(floorplan, ceiling_height, lo, width=size, padding=padding)
    return AtlasLayout(layout.floorplan, layout.ceiling_height, layout.texels_per_m, size, size, layout.surfaces)
