"""Coarse model atlas (paper §4.1): layout, texel -> world mapping, and the prism mesh,
against independent references."""

from __future__ import annotations

import glob
import math
from pathlib import Path

import numpy as np
import pytest
from locations import REPO

from probeless.coarse.atlas import fit_atlas, layout_atlas
from probeless.coarse.texels import coarse_mesh, texel_map
from probeless.errors import GeometryError
from probeless.geom.polygon import contains
from probeless.scene.parse import load_scene

ROOT = REPO
SCENES = sorted(glob.glob(str(ROOT / "launch/scenes/*.yaml")))

HAND_MADE = {
    # rectangle with collinear vertices on two of its sides
    "collinear_rect": ([[0, 0], [2, 0], [4, 0], [4, 3], [2, 3], [0, 3], [0, 1.5]], 2.4),
    # U shape, collinear vertex at the bottom and one on a reflex notch wall
    "u_shape": ([[0, 0], [3, 0], [6, 0], [6, 4], [4, 4], [4, 2], [4, 1.5], [2, 1.5], [2, 4], [0, 4]], 2.5),
    # oblique walls (non axis-aligned), non-convex
    "arrow": ([[0, 0], [3, 1], [6, 0], [5, 3], [3, 2], [1, 3]], 3.0),
    "triangle": ([[0, 0], [4, 0], [1, 3]], 2.2),
}


def _rooms():
    rooms = {Path(p).stem: (load_scene(p).floorplan, load_scene(p).ceiling_height) for p in SCENES}
    rooms.update({k: (np.array(v, float), h) for k, (v, h) in HAND_MADE.items()})
    return rooms


ROOMS = _rooms()


def _edges(poly):
    return [(poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))]


def _shoelace(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def _dist_to_segment(p, a, b):
    """Distance of points p (M, 2) to segment ab."""
    t = np.clip(((p - a) @ (b - a)) / np.dot(b - a, b - a), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1)


def test_shipped_scenes_are_found():
    assert len(SCENES) >= 4


@pytest.mark.parametrize("name", sorted(ROOMS))
@pytest.mark.parametrize("density", [7.3, 40.0])
def test_uniform_density_rect_sizes(name, density):
    poly, h = ROOMS[name]
    lay = layout_atlas(poly, h, density)
    assert lay.texels_per_m == density
    assert len(lay.surfaces) == len(poly) + 2
    expected_m = [(float(np.linalg.norm(b - a)), h) for a, b in _edges(np.asarray(poly, float))]
    ext = np.ptp(np.asarray(poly, float), axis=0)
    expected_m += [(ext[0], ext[1])] * 2
    for s, (mu, mv) in zip(lay.surfaces, expected_m):
        assert s.size_m == pytest.approx((mu, mv), abs=1e-12)
        assert s.rect[2:] == (max(1, math.ceil(mu * density)), max(1, math.ceil(mv * density))), s.name
    assert [s.kind for s in lay.surfaces] == ["wall"] * len(poly) + ["floor", "ceiling"]


@pytest.mark.parametrize("name", sorted(ROOMS))
def test_texel_spacing_is_the_same_on_every_surface(name):
    """Neighbouring core texels are 1/d metres apart along both atlas axes, on walls, floor and ceiling alike."""
    poly, h = ROOMS[name]
    d = 25.0
    lay = layout_atlas(poly, h, d)
    tm = texel_map(lay)
    for k, s in enumerate(lay.surfaces):
        both_c = tm.core[:, :-1] & tm.core[:, 1:] & (tm.surface[:, :-1] == k) & (tm.surface[:, 1:] == k)
        both_r = tm.core[:-1] & tm.core[1:] & (tm.surface[:-1] == k) & (tm.surface[1:] == k)
        dc = np.linalg.norm(tm.position[:, 1:] - tm.position[:, :-1], axis=2)[both_c]
        dr = np.linalg.norm(tm.position[1:] - tm.position[:-1], axis=2)[both_r]
        assert len(dc) and len(dr), s.name
        np.testing.assert_allclose(dc, 1 / d, atol=1e-5)
        np.testing.assert_allclose(dr, 1 / d, atol=1e-5)


def _assert_packed(lay, padding, width, height):
    rects = [s.rect for s in lay.surfaces]
    for x0, y0, w, h in rects:
        assert x0 - padding >= 0 and y0 - padding >= 0
        assert x0 + w + padding <= width and y0 + h + padding <= height
    for i in range(len(rects)):
        for j in range(i + 1, len(rects)):
            a, b = rects[i], rects[j]
            # rectangles grown by padding on each side must not overlap (so >= 2 * padding texels apart)
            apart = (a[0] + a[2] + padding <= b[0] - padding or b[0] + b[2] + padding <= a[0] - padding or
                     a[1] + a[3] + padding <= b[1] - padding or b[1] + b[3] + padding <= a[1] - padding)
            assert apart, (lay.surfaces[i].name, lay.surfaces[j].name, a, b)


@pytest.mark.parametrize("name", sorted(ROOMS))
@pytest.mark.parametrize("padding", [0, 1, 2, 5])
def test_rects_inside_atlas_and_disjoint(name, padding):
    poly, h = ROOMS[name]
    lay = layout_atlas(poly, h, 31.0, padding=padding)
    _assert_packed(lay, padding, lay.width, lay.height)
    occupancy = np.zeros((lay.height, lay.width), int)
    for x0, y0, w, hh in (s.rect for s in lay.surfaces):
        occupancy[y0:y0 + hh, x0:x0 + w] += 1
    assert occupancy.max() == 1


@pytest.mark.parametrize("name", sorted(ROOMS))
@pytest.mark.parametrize("size", [256, 2048])
def test_fit_atlas_is_densest_that_fits(name, size):
    poly, h = ROOMS[name]
    lay = fit_atlas(poly, h, size)
    assert (lay.width, lay.height) == (size, size)
    _assert_packed(lay, 2, size, size)
    same = layout_atlas(poly, h, lay.texels_per_m, width=size)
    assert [s.rect for s in same.surfaces] == [s.rect for s in lay.surfaces]
    try:
        denser = layout_atlas(poly, h, lay.texels_per_m * 1.01, width=size)
        assert denser.height > size
    except GeometryError as e:  # a surface no longer fits across
        assert "wider than the atlas" in str(e)


def _texel_uv(rc, lay):
    r, c = rc[:, 0], rc[:, 1]
    return np.stack([(c + 0.5) / lay.width, 1 - (r + 0.5) / lay.height], axis=1)


def _barycentric(p, a, b, c):
    """Barycentric weights (M, T, 3) of 2D points p (M, 2) in triangles a, b, c (T, 2)."""
    v0, v1, v2 = b - a, c - a, p[:, None, :] - a[None]
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    w1 = (v2[..., 0] * v1[:, 1] - v1[:, 0] * v2[..., 1]) / den
    w2 = (v0[:, 0] * v2[..., 1] - v2[..., 0] * v0[:, 1]) / den
    return np.stack([1 - w1 - w2, w1, w2], axis=-1)


@pytest.mark.parametrize("name", sorted(ROOMS))
def test_texel_map_matches_mesh_interpolation(name):
    poly, h = ROOMS[name]
    lay = fit_atlas(poly, h, 384)
    tm = texel_map(lay)
    verts, tris, uvs, tri_surface = coarse_mesh(lay)
    rng = np.random.default_rng(7)
    for k, s in enumerate(lay.surfaces):
        rc = np.argwhere(tm.core & (tm.surface == k))
        assert len(rc) > 0, s.name
        rc = rc[rng.choice(len(rc), min(300, len(rc)), replace=False)]
        mine = tris[tri_surface == k]
        uv = _texel_uv(rc, lay)
        w = _barycentric(uv, uvs[mine[:, 0]].astype(float), uvs[mine[:, 1]].astype(float),
                         uvs[mine[:, 2]].astype(float))
        inside = (w >= -1e-6).all(axis=2)
        assert inside.any(axis=1).all(), f"{s.name}: a core texel's uv lies in none of its surface's triangles"
        t = inside.argmax(axis=1)
        wt = w[np.arange(len(rc)), t]
        world = np.einsum("mk,mkj->mj", wt, verts[mine[t]].astype(float))
        np.testing.assert_allclose(tm.position[rc[:, 0], rc[:, 1]], world, atol=1e-4, err_msg=s.name)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(ROOMS))
def test_positions_on_prism_and_normals_inward(name):
    poly, h = ROOMS[name]
    poly = np.asarray(poly, float)
    lay = layout_atlas(poly, h, 40.0)
    tm = texel_map(lay)
    step, margin = 0.01, 0.02  # 1 cm along the normal; texels >= 2 cm from a wall's ends (corners up to ~30 deg)
    for k, s in enumerate(lay.surfaces):
        on = tm.surface == k
        p, n = tm.position[on].astype(float), tm.normal[on].astype(float)
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1, atol=1e-6)
        if s.kind == "wall":
            a, b = poly[k], poly[(k + 1) % len(poly)]
            assert _dist_to_segment(p[:, :2], a, b).max() < 1e-5, s.name
            assert p[:, 2].min() >= -1e-6 and p[:, 2].max() <= h + 1e-6
            core = tm.core[on]
            along = (p[:, :2] - a) @ (b - a) / np.linalg.norm(b - a)
            away = core & (along > margin) & (along < np.linalg.norm(b - a) - margin)
            assert away.sum() > 0
            assert contains(poly, p[away, :2] + step * n[away, :2]).all(), s.name
            assert not contains(poly, p[away, :2] - step * n[away, :2]).any(), s.name
            assert np.abs(n[:, 2]).max() < 1e-6
        else:
            z = 0.0 if s.kind == "floor" else h
            np.testing.assert_allclose(p[:, 2], z, atol=1e-6)
            stepped = p[:, 2] + step * n[:, 2]
            assert ((stepped > 0) & (stepped < h)).all(), s.name
            core_xy = p[tm.core[on], :2]
            off = core_xy[~contains(poly, core_xy)]  # only centres exactly on an edge may test as outside
            assert len(off) == 0 or np.min([_dist_to_segment(off, a, b) for a, b in _edges(poly)], axis=0).max() < 1e-6


@pytest.mark.parametrize("name", sorted(ROOMS))
def test_floor_and_ceiling_triangulation_covers_polygon(name):
    poly, h = ROOMS[name]
    poly = np.asarray(poly, float)
    lay = layout_atlas(poly, h, 10.0)
    verts, tris, _, tri_surface = coarse_mesh(lay)
    rng = np.random.default_rng(3)
    lo, hi = poly.min(0), poly.max(0)
    samples = rng.uniform(lo, hi, (4000, 2))
    inside = contains(poly, samples)
    for k, s in enumerate(lay.surfaces):
        t = tris[tri_surface == k]
        a, b, c = (verts[t[:, i]].astype(float) for i in range(3))
        facing = np.cross(b - a, c - a) @ s.normal
        assert (facing >= -1e-9).all(), f"{s.name}: a triangle faces out of the room"
        assert (facing > 1e-9).any()
        if s.kind == "wall":
            assert np.sum(np.linalg.norm(np.cross(b - a, c - a), axis=1)) / 2 == pytest.approx(s.size_m[0] * h)
            continue
        assert np.sum(np.abs(facing)) / 2 == pytest.approx(_shoelace(poly), rel=1e-6)  # float32 vertices
        real = facing > 1e-9  # collinear floorplan vertices may give zero-area triangles
        w = _barycentric(samples, a[real, :2], b[real, :2], c[real, :2])
        hits = (w >= 1e-9).all(axis=2).sum(axis=1)
        assert (hits[inside] == 1).all(), s.name
        assert (hits[~inside] == 0).all(), s.name


@pytest.mark.parametrize("name", sorted(ROOMS))
def test_core_floor_texels_match_area(name):
    poly, h = ROOMS[name]
    poly = np.asarray(poly, float)
    d = 30.0
    lay = layout_atlas(poly, h, d)
    tm = texel_map(lay)
    perimeter = sum(np.linalg.norm(b - a) for a, b in _edges(poly))
    for kind in ("floor", "ceiling"):
        k = [s.kind for s in lay.surfaces].index(kind)
        count = int((tm.core & (tm.surface == k)).sum())
        assert abs(count - _shoelace(poly) * d * d) <= 0.5 * perimeter * d, (kind, count)
        # floor/ceiling texels outside the polygon are only a one-texel rim around it
        rim = (tm.surface == k) & ~tm.core
        rim_xy = tm.position[rim][:, :2].astype(float)
        dist = np.min([_dist_to_segment(rim_xy, a, b) for a, b in _edges(poly)], axis=0)
        assert dist.max() <= math.sqrt(2) / d + 1e-6


@pytest.mark.parametrize("padding", [0, 1, 2])
def test_rings_never_take_another_surfaces_texels(padding):
    poly, h = ROOMS["l_shaped_lounge"]
    lay = layout_atlas(poly, h, 37.0, padding=padding)
    tm = texel_map(lay)
    for k, s in enumerate(lay.surfaces):
        x0, y0, w, hh = s.rect
        own = tm.surface[y0:y0 + hh, x0:x0 + w]
        if s.kind == "wall":
            assert (own == k).all(), s.name
        assert (tm.core[y0:y0 + hh, x0:x0 + w] <= (own == k)).all()
    # with padding 2 every wall's 2-texel ring belongs to that wall, clamped onto it
    if padding == 2:
        for k, s in enumerate(lay.walls):
            x0, y0, w, hh = s.rect
            ring = tm.surface[y0 - 2:y0 + hh + 2, x0 - 2:x0 + w + 2]
            assert (ring == k).all(), s.name


@pytest.mark.parametrize("poly, h, what", [
    ([[0, 0], [0, 3], [4, 3], [4, 0]], 2.5, "counter-clockwise"),
    ([[0, 0], [4, 0], [0, 3], [4, 3]], 2.5, "intersect"),
    ([[0, 0], [4, 0], [4, 3], [2, -1], [0, 3]], 2.5, "intersect"),
    ([[0, 0], [4, 0], [4, 3], [0, 3]], 0.0, "ceiling_height"),
    ([[0, 0], [4, 0], [4, 3], [0, 3]], -1.0, "ceiling_height"),
    ([[0, 0], [4, 0], [4, 3], [0, 3]], float("nan"), "ceiling_height"),
    ([[0, 0], [4, 0], [4, float("nan")], [0, 3]], 2.5, "non-finite"),
    ([[0, 0], [4, 0]], 2.5, "N >= 3"),
    ([[0, 0], [4, 0], [4, 0], [4, 3], [0, 3]], 2.5, "intersect|coincide"),
])
def test_bad_geometry_raises(poly, h, what):
    for fn in (lambda: layout_atlas(poly, h, 10.0), lambda: fit_atlas(poly, h, 256)):
        with pytest.raises(GeometryError, match=what):
            fn()


def test_bad_density_raises():
    for d in (0.0, -3.0, float("nan"), float("inf")):
        with pytest.raises(GeometryError, match="texels_per_m"):
            layout_atlas([[0, 0], [4, 0], [4, 3], [0, 3]], 2.5, d)
