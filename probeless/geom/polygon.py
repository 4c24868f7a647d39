"""2-D polygon predicates for floorplans (vertices (N, 2), not closed);
the validator: :mod:`probeless.geom.floorplan`."""

from __future__ import annotations

import numpy as np


def cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z component of the cross product of 2-D vectors (..., 2) x (..., 2) -> (...)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def signed_area(poly: np.ndarray) -> float:
    """Shoelace area [m^2]; positive when the vertices run counter-clockwise (seen from above, z up)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))


def _on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> bool:
    return min(a[0], b[0]) - 1e-12 <= p[0] <= max(a[0], b[0]) + 1e-12 and \
        min(a[1], b[1]) - 1e-12 <= p[1] <= max(a[1], b[1]) + 1e-12


def segments_intersect(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """True when closed segments ab and cd share a point (touching counts)."""
    o1, o2, o3, o4 = _orient(a, b, c), _orient(a, b, d), _orient(c, d, a), _orient(c, d, b)
    if (o1 > 0) != (o2 > 0) and (o3 > 0) != (o4 > 0) and o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return any(abs(o) < 1e-12 and _on_segment(s, e, p)
               for o, s, e, p in ((o1, a, b, c), (o2, a, b, d), (o3, c, d, a), (o4, c, d, b)))


def self_intersection(poly: np.ndarray) -> tuple[int, int] | None:
    """Indices (i, j) of two non-adjacent edges that touch or cross, or None for a simple polygon.

    Edge i runs from vertex i to vertex i + 1 (mod n).
    """
    n = len(poly)
    for i in range(n):
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):
                continue
            if segments_intersect(poly[i], poly[(i + 1) % n], poly[j], poly[(j + 1) % n]):
                return i, j
    return None


def contains(poly: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(M,) bool: which points (M, 2) lie strictly inside the polygon (even-odd rule)."""
    pts = np.atleast_2d(points)
    x, y = pts[:, 0:1], pts[:, 1:2]
    x0, y0 = poly[:, 0][None, :], poly[:, 1][None, :]
    x1, y1 = np.roll(poly[:, 0], -1)[None, :], np.roll(poly[:, 1], -1)[None, :]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    inside = (np.sum(crosses & (x < x_at), axis=1) % 2) == 1
    return inside & (distance_to_boundary(poly, pts) > 1e-9)


def distance_to_boundary(poly: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(M,) distance of each point (M, 2) to the nearest polygon edge [m]."""
    pts = np.atleast_2d(points)[:, None, :]
    a = poly[None, :, :]
    ab = np.roll(poly, -1, axis=0)[None, :, :] - a
    t = np.clip(np.sum((pts - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-300), 0.0, 1.0)
    nearest = a + t[..., None] * ab
    return np.min(np.linalg.norm(pts - nearest, axis=2), axis=1)
