"""Exact 2-D visibility polygon of a floorplan from the fisheye's floor position (paper §4.4).

The coarse model is a right prism, so it hides parts of itself only through its floorplan: a
texel can be seen when its floor point lies in the visibility polygon of the floorplan from the
camera's floor position. Floorplans are (N, 2) float64 vertex arrays, counter-clockwise, not closed,
checked by :func:`probeless.geom.floorplan.check_floorplan`.
"""

from __future__ import annotations

import numpy as np

from probeless.errors import GeometryError
from probeless.geom.floorplan import check_floorplan, tolerance
from probeless.geom.polygon import contains, cross2, distance_to_boundary, signed_area

ANG_TOL = 1e-12    # directions from the viewpoint closer than this [rad] are one ray


def is_convex(floorplan) -> bool:
    """True when the (valid) floorplan is convex; collinear vertices allowed. The texturer then skips occlusion."""
    poly = check_floorplan(floorplan)
    edge = np.roll(poly, -1, axis=0) - poly
    nxt = np.roll(edge, -1, axis=0)
    return bool(np.all(cross2(edge, nxt) >= -tolerance(poly) * np.linalg.norm(nxt, axis=1)))


def _locate(poly: np.ndarray, p: np.ndarray, tol: float) -> tuple[str, int, np.ndarray]:
    """("vertex", i, vertex i) / ("edge", i, p on edge i) / ("inside", -1, p); GeometryError when outside."""
    dv = np.linalg.norm(poly - p, axis=1)
    if dv.min() <= tol:
        i = int(np.argmin(dv))
        return "vertex", i, poly[i].copy()
    edge = np.roll(poly, -1, axis=0) - poly
    t = np.clip(np.sum((p - poly) * edge, axis=1) / np.sum(edge * edge, axis=1), 0.0, 1.0)
    foot = poly + t[:, None] * edge
    de = np.linalg.norm(p - foot, axis=1)
    if de.min() <= tol:
        i = int(np.argmin(de))
        return "edge", i, foot[i]
    with np.errstate(over="ignore"):   # polygon.contains overflows harmlessly on near-horizontal edges
        inside = contains(poly, p)[0]
    if not inside:
        raise GeometryError(f"viewpoint {p.tolist()} is outside the floorplan (by {de.min():.3g} m)")
    return "inside", -1, p


def _rel_angles(rel: np.ndarray, unit: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Counter-clockwise angles [0, 2 pi) of directions ``rel`` from ``ref``, and which point along ``ref``."""
    ang = np.mod(np.arctan2(rel[:, 1], rel[:, 0]) - np.arctan2(ref[1], ref[0]), 2 * np.pi)
    r = ref / np.linalg.norm(ref)
    return ang, (np.abs(cross2(r, unit)) <= ANG_TOL) & (unit @ r > 0)


def _first_hits(poly: np.ndarray, p: np.ndarray, d: np.ndarray, label: np.ndarray,
                skip: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """(G, 2) each: nearest boundary points hit by rays from ``p`` along unit ``d`` (G, 2) turned slightly cw, ccw.

    An edge is hit when it crosses the ray's line properly ahead of ``p``, or has one endpoint on
    the ray (``label`` == ray index) and the other on the side the ray turns to. Edges in ``skip``
    (those through ``p``) are ignored. NaN where nothing is hit. O(G N).
    """
    rays = np.arange(len(d))[:, None]
    u, w = poly, np.roll(poly, -1, axis=0)
    on_u, on_w = label[None, :] == rays, np.roll(label, -1)[None, :] == rays
    su, sw = cross2(d[:, None], (u - p)[None]), cross2(d[:, None], (w - p)[None])
    with np.errstate(divide="ignore", invalid="ignore"):
        cut = u[None] + (su / (su - sw))[..., None] * (w - u)[None]   # NaN/inf where the edge is parallel
        t_cut = (cut[..., 0] - p[0]) * d[:, 0:1] + (cut[..., 1] - p[1]) * d[:, 1:2]
    t_cross = np.where(~on_u & ~on_w & (su * sw < 0) & (t_cut > 0), t_cut, np.inf)
    t_cross[:, skip] = np.inf
    t_u, t_w = np.where(on_u & ~on_w, d @ (u - p).T, np.inf), np.where(on_w & ~on_u, d @ (w - p).T, np.inf)
    t_u[:, skip], t_w[:, skip] = np.inf, np.inf
    g, n = rays[:, 0], len(poly)
    hits = []
    for side in (-1, 1):
        t = np.concatenate([t_cross, np.where(side * sw > 0, t_u, np.inf),
                            np.where(side * su > 0, t_w, np.inf)], axis=1)
        best = np.argmin(t, axis=1)
        source, e = best // n, best % n   # 0: a crossing, 1: edge start on the ray, 2: edge end on the ray
        hit = np.where((source == 0)[:, None], cut[g, e], np.where((source == 1)[:, None], u[e], w[e]))
        hit[~np.isfinite(t[g, best])] = np.nan   # rays leaving the room at p
        hits.append(hit)
    return hits[0], hits[1]


def _simplify(pts: np.ndarray, tol: float) -> np.ndarray:
    """Drop repeated consecutive vertices and vertices within ``tol`` of the straight line through their neighbours."""
    while len(pts) > 3:
        pts = pts[np.linalg.norm(pts - np.roll(pts, 1, axis=0), axis=1) > tol]
        ab, bc = pts - np.roll(pts, 1, axis=0), np.roll(pts, -1, axis=0) - pts
        ac = ab + bc
        straight = (np.sum(ab * bc, axis=1) > 0) & (np.abs(cross2(ac, ab)) <= tol * np.linalg.norm(ac, axis=1))
        if not straight.any():
            break
        pts = pts[~straight]
    return pts


def visibility_polygon(floorplan, viewpoint) -> np.ndarray:
    """(M, 2) counter-clockwise polygon of the points of ``floorplan`` seen from ``viewpoint``.

    ``floorplan`` is a simple counter-clockwise (N, 2) polygon, possibly non-convex, collinear
    vertices allowed; ``viewpoint`` (2,) lies inside it or on its boundary (an edge or a vertex,
    within 1e-9 of the room size). Exact up to rounding, and regularised (as CGAL's): zero-width
    needles seen through two vertices on one ray are left out. No repeated or collinear vertices.

    Rotational ray casting: rays through every vertex direction, each cast twice, turned an
    infinitesimal amount clockwise and counter-clockwise, so a ray grazing a reflex vertex stops
    on the blocked side and goes on on the other; between two such directions the visible
    boundary is a part of one edge. O(N^2) time and memory, vectorised (~2 ms for N = 100).
    GeometryError for an invalid floorplan or a viewpoint outside it.
    """
    poly = check_floorplan(floorplan)
    n, tol = len(poly), tolerance(poly)
    p = np.asarray(viewpoint, dtype=np.float64).reshape(-1)
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise GeometryError(f"viewpoint must be two finite numbers, got {np.asarray(viewpoint).tolist()}")
    kind, k, p = _locate(poly, p, tol)
    rel = poly - p
    dist = np.linalg.norm(rel, axis=1)
    unit = rel / np.where(dist > 0, dist, 1.0)[:, None]
    if kind == "inside":
        start, end, skip = rel[0], None, []
    elif kind == "vertex":   # the room near p: counter-clockwise from the next vertex to the previous one
        start, end, skip = rel[(k + 1) % n], rel[k - 1], [(k - 1) % n, k]
    else:
        start, end, skip = rel[(k + 1) % n], rel[k], [k]
    ang, along = _rel_angles(rel, unit, start)
    ang[along] = 0.0
    width = 2 * np.pi
    if end is not None:
        width = float(np.mod(np.arctan2(end[1], end[0]) - np.arctan2(start[1], start[0]), 2 * np.pi))
        ang[_rel_angles(rel, unit, end)[1]] = width
    cand = np.flatnonzero((dist > tol) & (ang <= width))
    cand = cand[np.argsort(ang[cand], kind="stable")]
    group = np.concatenate([[0], np.cumsum(np.diff(ang[cand]) > ANG_TOL)])
    label = np.full(n, -1)
    label[cand] = group
    by_dist = np.lexsort((dist[cand], group))
    d = unit[cand[by_dist[np.unique(group[by_dist], return_index=True)[1]]]]   # towards each ray's nearest vertex
    cw, ccw = _first_hits(poly, p, d, label, skip)
    pts = np.stack([cw, ccw], axis=1).reshape(-1, 2)
    if end is not None:   # rays outside the room's angle at p see nothing: p, then ccw of the first ray ...
        if ang[cand[0]] != 0.0 or ang[cand[-1]] != width or group[-1] < 1:
            raise GeometryError(f"degenerate corner at viewpoint {p.tolist()}")
        pts = np.concatenate([p[None], pts[1:-1]])
    if np.isnan(pts).any():
        raise GeometryError(f"a ray from viewpoint {p.tolist()} hits no wall of the floorplan (degenerate input)")
    vis = _simplify(pts, tol)
    if len(vis) < 3 or signed_area(vis) <= 0:
        raise GeometryError(f"empty visibility polygon from viewpoint {p.tolist()} (degenerate input)")
    return vis


def visible_from(floorplan, viewpoint, points) -> np.ndarray:
    """(K,) bool brute-force reference: the segment from ``viewpoint`` to each point stays in the closed floorplan.

    The segment must cross no edge properly, and between consecutive boundary contacts (vertices
    on it, its ends) its midpoints must be inside or on the boundary. ``viewpoint`` is not snapped
    or checked. O(K N), independent of :func:`visibility_polygon`; for tests and references.
    """
    poly = check_floorplan(floorplan)
    tol = tolerance(poly)
    p = np.asarray(viewpoint, dtype=np.float64).reshape(2)
    q = np.atleast_2d(np.asarray(points, dtype=np.float64))
    a, edge = poly, np.roll(poly, -1, axis=0) - poly
    elen = np.linalg.norm(edge, axis=1)
    dq = q - p
    qlen = np.maximum(np.linalg.norm(dq, axis=1), 1e-150)[:, None]
    oa = cross2(dq[:, None], (a - p)[None]) / qlen               # vertices' distances from each segment's line
    ob = np.roll(oa, -1, axis=1)
    op = cross2(edge, p - a)[None] / elen                         # segment ends' distances from each edge's line
    oq = cross2(edge[None], q[:, None] - a[None]) / elen[None]
    proper = (oa * ob < 0) & (op * oq < 0) & (np.minimum(np.abs(oa), np.abs(ob)) > tol) \
        & (np.minimum(np.abs(op), np.abs(oq)) > tol)
    ta = np.sum((a[None] - p) * dq[:, None], axis=2) / qlen ** 2
    touch = (np.abs(oa) <= tol) & (ta > 0) & (ta < 1)
    mids, owner = [], []
    for i in range(len(q)):
        s = np.unique(np.concatenate([[0.0, 1.0], ta[i, touch[i]]]))
        mids.append(p + 0.5 * (s[:-1] + s[1:])[:, None] * dq[i])
        owner.append(np.full(len(s) - 1, i))
    mids, owner = np.concatenate(mids), np.concatenate(owner)
    with np.errstate(over="ignore"):
        inside = contains(poly, mids) | (distance_to_boundary(poly, mids) <= tol)
    ok = np.ones(len(q), bool)
    np.logical_and.at(ok, owner, inside)
    return ok & ~proper.any(axis=1)
