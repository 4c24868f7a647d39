"""CPU occlusion of atlas texels from the 2-D visibility polygon (paper §4.4).

The coarse model is a right prism, so a texel is visible from the fisheye when its floor point
(x, y) can be seen from the camera's floor position inside the floorplan polygon: the visibility
polygon. Wall texels lie on the polygon's boundary, so they are tested ``offset_m`` inside the room
along their inward normal (floor and ceiling normals are vertical: no offset). This is the
reference of the texturer's GPU occlusion mask, and what the brightness estimator uses.
"""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path

from probeless.coarse.visibility import is_convex, visibility_polygon


def floor_points(positions: np.ndarray, normals: np.ndarray, offset_m: float) -> np.ndarray:
    """(N, 2) floor points at which texels are tested: (x, y) moved ``offset_m`` along the normal's (x, y)."""
    p = np.asarray(positions)[:, :2].astype(np.float64)
    return p + offset_m * np.asarray(normals)[:, :2]


def texel_visible(positions: np.ndarray, normals: np.ndarray, floorplan: np.ndarray, viewpoint_xy: np.ndarray,
                  *, offset_m: float) -> np.ndarray:
    """(N,) bool: the texels at world ``positions`` with inward ``normals`` are not hidden by the room itself.

    All True for a convex floorplan (the prism cannot occlude itself). Otherwise the test point of
    each texel must lie in ``visibility_polygon(floorplan, viewpoint_xy)``; GeometryError from it
    (viewpoint outside the room) propagates.
    """
    if is_convex(floorplan):
        return np.ones(len(positions), bool)
    poly = visibility_polygon(np.asarray(floorplan, np.float64), np.asarray(viewpoint_xy, np.float64)[:2])
    return inside(poly, positions, normals, offset_m)


def inside(poly: np.ndarray, positions: np.ndarray, normals: np.ndarray, offset_m: float) -> np.ndarray:
    """(N,) bool: the texels' floor points (:func:`floor_points`) lie in the polygon ``poly`` (M, 2)."""
    return Path(poly).contains_points(floor_points(positions, normals, offset_m))


def polygon_contains(poly: list[tuple[float, float]], x: float, y: float) -> bool:
    """Even-odd ray crossing test of one point, in plain Python (the serial reference's per-texel test)."""
    inside = False
    n = len(poly)
    xj, yj = poly[n - 1]
    for i in range(n):
        xi, yi = poly[i]
        if (yi > y) != (yj > y) and x < (xj - xi) * (y - yi) / (yj - yi) + xi:
            inside = not inside
        xj, yj = xi, yi
    return inside
