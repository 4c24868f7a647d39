"""Dark specks of the dense splats (issue 17): a table seen from just above its top must show the top only.

A dense model of a box table on a 2 cm lattice (bright top, dark sides) over a bright floor. From 16 cm above
the top nothing darker than the top or the floor is visible. Before the fix, the round 2 cm splats left the
lattice's diagonal gaps open and the sides (seen from behind, through the top) showed there as dark specks.
DensePoints' normals are checked against analytic planes.
"""

from __future__ import annotations

import numpy as np
import pytest

from probeless.coarse.atlas import fit_atlas
from probeless.envmap.cubemap import SPLAT_COVER, EnvmapRenderer
from probeless.envmap.dense_points import DensePoints, grid_normals

VOXEL = 0.02
TOP, SIDE, FLOOR = 190, 60, 200
EYE = np.array([2.0, 1.5, 0.90])


def lattice(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (g.ravel() for g in np.meshgrid(u, v, indexing="ij"))


def table_cloud() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points, colours uint8, outward normals) of a 1.2 x 0.8 x 0.74 m box table and the floor around it."""
    c = VOXEL / 2
    xs, ys, zs = np.arange(1.4 + c, 2.6, VOXEL), np.arange(1.1 + c, 1.9, VOXEL), np.arange(c, 0.74, VOXEL)
    parts = []
    x, y = lattice(xs, ys)
    parts.append((np.c_[x, y, np.full_like(x, 0.74 - c)], TOP, (0, 0, 1)))
    for x0, n in ((1.4 + c, (-1, 0, 0)), (2.6 - c, (1, 0, 0))):
        y, z = lattice(ys, zs)
        parts.append((np.c_[np.full_like(y, x0), y, z], SIDE, n))
    for y0, n in ((1.1 + c, (0, -1, 0)), (1.9 - c, (0, 1, 0))):
        x, z = lattice(xs, zs)
        parts.append((np.c_[x, np.full_like(x, y0), z], SIDE, n))
    x, y = lattice(np.arange(0.6 + c, 3.4, VOXEL), np.arange(0.3 + c, 2.7, VOXEL))
    out = ~((x > 1.4) & (x < 2.6) & (y > 1.1) & (y < 1.9))
    parts.append((np.c_[x[out], y[out], np.full(out.sum(), c)], FLOOR, (0, 0, 1)))
    pts = np.concatenate([p for p, _, _ in parts])
    cols = np.concatenate([np.full((len(p), 3), k, np.uint8) for p, k, _ in parts])
    nrm = np.concatenate([np.tile(np.asarray(n, np.float32), (len(p), 1)) for p, _, n in parts])
    return pts.astype(np.float32), cols, nrm


@pytest.fixture(scope="module")
def renderer():
    layout = fit_atlas(np.array([[0.0, 0], [4, 0], [4, 3], [0, 3]]), 2.5, 256)
    r = EnvmapRenderer(layout)
    atlas = np.full((layout.height, layout.width, 4), 255, np.uint8)
    atlas[..., :3] = FLOOR
    r.set_atlas(atlas)
    yield r
    r.release()


@pytest.mark.gl
def test_no_texel_darker_than_the_surfaces_it_shows(renderer):
    pts, cols, nrm = table_cloud()
    renderer.set_dense(pts, cols, normals=nrm)
    faces = renderer.render(EYE, 64, splat_m=SPLAT_COVER * VOXEL)
    # everything visible from above the top is the top (190) or the floor / walls (200): no dark speck
    assert faces.min() * 255 > TOP - 10, f"{(faces.max(axis=-1) * 255 < TOP - 10).sum()} dark texels"
    # -Z: the table top only (within a splat radius of the face edges the coarse floor shows: GL clips a point
    # sprite by its centre, so splats centred on the next face do not reach this one)
    np.testing.assert_allclose(faces[5, 3:-3, 3:-3], TOP / 255, atol=1e-6)
    # the test can fail: the old splats (diameter = spacing, no normals) leave the sides showing through
    renderer.set_dense(pts, cols)
    old = renderer.render(EYE, 64, splat_m=VOXEL)
    assert (old.max(axis=-1) * 255 < TOP - 10).sum() > 20
    renderer.clear_dense()


@pytest.mark.gl
def test_backfacing_points_are_dropped_and_unknown_normals_kept(renderer):
    p = np.array([[2.0, 1.5, 0.3]], np.float32)  # 0.6 m below the eye
    blue = np.array([[0, 0, 255]], np.uint8)
    for normal, drawn in (((0, 0, 1), True), ((0, 0, -1), False), ((1, 0, 0), False), ((0, 0, 0), True)):
        renderer.set_dense(p, blue, normals=np.array([normal], np.float32))
        faces = renderer.render(EYE, 64, splat_m=0.05)
        assert (faces[5, ..., 2] > 0.99).any() == drawn, normal
    renderer.clear_dense()


def test_dense_points_normals_of_planes_seen_obliquely():
    K = np.array([[200.0, 0, 79.5], [0, 200.0, 59.5], [0, 0, 1]])
    h, w = 120, 160
    # camera at (0, 0, 1.5) looking along +y, pitched 40 deg down; world z up
    a = np.radians(40)
    R = np.array([[1, 0, 0], [0, -np.sin(a), np.cos(a)], [0, -np.cos(a), -np.sin(a)]])  # columns: cam x, y, z
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, (0, 0, 1.5)
    v, u = np.mgrid[0:h, 0:w]
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones((h, w))], -1) @ R.T
    t_floor = np.where(rays[..., 2] < 0, -1.5 / np.minimum(rays[..., 2], -1e-9), np.inf)
    t_wall = np.where(rays[..., 1] > 0, 2.5 / np.maximum(rays[..., 1], 1e-9), np.inf)  # wall y = 2.5
    depth = np.minimum(t_floor, t_wall)  # camera z of a ray (x, y, 1) is its parameter t
    dense = DensePoints(np.array([[0.0, 2.0, 0.5]]), radius_m=5.0, step=2)
    dense.add(np.full((h, w, 3), 128, np.uint8), depth, K, T)
    pts, nrm = dense.points()[0], dense.normals()
    floor = (pts[:, 2] < 0.05) & (pts[:, 1] < 2.3)
    wall = (pts[:, 1] > 2.45) & (pts[:, 2] > 0.1)
    known = np.linalg.norm(nrm, axis=1) > 0.5
    assert floor.sum() > 100 and wall.sum() > 100 and known[floor].mean() > 0.9
    np.testing.assert_allclose(nrm[floor & known], [[0, 0, 1]] * (floor & known).sum(), atol=0.02)
    np.testing.assert_allclose(nrm[wall & known], [[0, -1, 0]] * (wall & known).sum(), atol=0.02)
    # the depth edge between the two planes gets no normal
    r, c = np.mgrid[0:5, 0:5] * 0.01
    grid = np.stack([c, r, np.where(c > 0.025, 2.0, 1.0)], axis=-1)
    n = grid_normals(grid)
    np.testing.assert_allclose(n[2, 1], [0, 0, -1])  # facing the camera at the origin
    assert not n[2, 2].any() and not n[0].any()  # across the edge; on the border
