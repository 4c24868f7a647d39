"""The one floorplan validator: the rules every floorplan of the project obeys.

A floorplan is the room's floor polygon, vertices (N, 2) [m, world x y], not closed. Valid means:

1. an (N, 2) array with N >= 3;
2. every coordinate finite;
3. no two consecutive vertices coincide;
4. not all vertices on one line (zero area);
5. no edge folds back onto the next one (a zero-width spike);
6. simple: no two non-adjacent edges touch or cross;
7. counter-clockwise seen from above (z up): positive signed area.

Collinear consecutive vertices (a straight angle) are allowed. Lengths within ``REL_TOL`` times the
room size count as zero. The message ``Floorplan``, the scene parser, the coarse atlas and the
visibility code all call :func:`check_floorplan` and re-raise its :class:`GeometryError` in their
own error type where they have one.
"""

from __future__ import annotations

import math

import numpy as np

from probeless.errors import GeometryError
from probeless.geom.polygon import cross2, signed_area

REL_TOL = 1e-9     # lengths below REL_TOL * room size [m] count as zero


def tolerance(poly: np.ndarray) -> float:
    """The length [m] below which distances in ``poly`` count as zero: REL_TOL times the room size (>= 1 m)."""
    return REL_TOL * max(1.0, float(np.ptp(poly, axis=0).max()))


def check_floorplan(floorplan, what: str = "floorplan") -> np.ndarray:
    """``floorplan`` as float64 (N, 2); GeometryError naming ``what`` unless it obeys the module's rules.

    O(N^2), vectorised.
    """
    poly = np.asarray(floorplan, dtype=np.float64)
    if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 3:
        raise GeometryError(f"{what}: need at least 3 vertices, an (N >= 3, 2) array, got shape {poly.shape}")
    if not np.all(np.isfinite(poly)):
        raise GeometryError(f"{what}: contains NaN or inf (non-finite coordinates)")
    n, tol = len(poly), tolerance(poly)
    a, edge = poly, np.roll(poly, -1, axis=0) - poly
    length = np.linalg.norm(edge, axis=1)
    if np.any(length <= tol):
        i = int(np.argmax(length <= tol))
        raise GeometryError(f"{what}: vertices {i} and {(i + 1) % n} coincide")
    far = int(np.argmax(np.linalg.norm(poly - poly[0], axis=1)))
    axis = (poly[far] - poly[0]) / np.linalg.norm(poly[far] - poly[0])
    if np.all(np.abs(cross2(poly - poly[0], axis)) <= tol):
        raise GeometryError(f"{what}: all vertices lie on one line (zero area), not a counter-clockwise polygon")
    nxt = np.roll(edge, -1, axis=0)
    fold = (np.abs(cross2(edge, nxt)) <= tol * np.roll(length, -1)) & (np.sum(edge * nxt, axis=1) < 0)
    if np.any(fold):
        raise GeometryError(f"{what}: folds back on itself at vertex {(int(np.argmax(fold)) + 1) % n}")
    # o0[i, j]: signed distance of vertex j from the line of edge i, t0 its position along edge i (0..1);
    # edge j's second endpoint is vertex j + 1
    dx, dy = a[None, :, 0] - a[:, None, 0], a[None, :, 1] - a[:, None, 1]
    ex, ey = edge[:, 0:1], edge[:, 1:2]
    o0, t0 = (ex * dy - ey * dx) / length[:, None], (ex * dx + ey * dy) / (length ** 2)[:, None]
    o1, t1 = np.roll(o0, -1, axis=1), np.roll(t0, -1, axis=1)
    straddle, clear = o0 * o1 < 0, np.minimum(np.abs(o0), np.abs(o1)) > tol
    proper = straddle & straddle.T & clear & clear.T
    slack = (tol / length)[:, None]
    touch = np.zeros((n, n), bool)
    for o, t in ((o0, t0), (o1, t1)):   # an endpoint of edge j within tol of segment i
        touch |= (np.abs(o) <= tol) & (t >= -slack) & (t <= 1 + slack)
    bad = proper | touch | touch.T
    i, j = np.indices((n, n))
    bad &= (j > i + 1) & ~((i == 0) & (j == n - 1))
    if np.any(bad):
        i, j = (int(v) for v in np.argwhere(bad)[0])
        raise GeometryError(f"{what}: not simple (self-intersecting): edges {i} and {j} touch or cross")
    area = signed_area(poly)
    if area <= 0:
        raise GeometryError(f"{what}: must be counter-clockwise seen from above (signed area {area:.6g} m^2 is "
                            f"not positive)")
    return poly


def check_ceiling_height(height: float, what: str = "ceiling_height") -> float:
    """``height`` as float; GeometryError naming ``what`` unless finite and > 0 [m]."""
    h = float(height)
    if not (math.isfinite(h) and h > 0):
        raise GeometryError(f"{what}: must be finite and > 0 m, got {height}")
    return h
