"""Unlighted splat renderings with point ids (paper 001, §4.1) and the automatic choice of their cameras."""

import cv2
import numpy as np
import pytest

from probeless.errors import HdrError
from probeless.geom.cube import texel_from_direction
from probeless.hdr.splat import SplatRenderer, check_cloud, point_spacing
from probeless.hdr.views import camera_looking_at, place_views, saturated_clusters, views_from_positions

ROOM = np.array([4.0, 3.0, 2.5])  # box room [0, 4] x [0, 3] x [0, 2.5] m


@pytest.fixture(scope="module")
def renderer():
    r = SplatRenderer()
    yield r
    r.release()


def box_surface(lo, hi, step, rng, jitter=0.3):
    """(points, inward normals) on the six faces of the box [lo, hi], a jittered grid of pitch ``step``."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pts, nrm = [], []
    for axis in range(3):
        a, b = [k for k in range(3) if k != axis]
        ua = np.arange(lo[a] + step / 2, hi[a], step)
        ub = np.arange(lo[b] + step / 2, hi[b], step)
        ga, gb = (g.ravel() for g in np.meshgrid(ua, ub, indexing="ij"))
        for side, sign in ((lo[axis], 1.0), (hi[axis], -1.0)):
            p = np.zeros((len(ga), 3))
            p[:, a] = ga + rng.uniform(-jitter, jitter, len(ga)) * step
            p[:, b] = gb + rng.uniform(-jitter, jitter, len(ga)) * step
            p[:, axis] = side
            n = np.zeros_like(p)
            n[:, axis] = sign
            pts.append(p)
            nrm.append(n)
    return np.concatenate(pts).astype(np.float32), np.concatenate(nrm).astype(np.float32)


def room_cloud(step=0.03, seed=0):
    rng = np.random.default_rng(seed)
    p, n = box_surface((0, 0, 0), ROOM, step, rng)
    c = rng.uniform(0.2, 0.6, (len(p), 3)).astype(np.float32)
    return p, n, c


@pytest.mark.slow
@pytest.mark.gl
def test_id_buffer_is_the_nearest_covering_point(renderer):
    rng = np.random.default_rng(1)
    g = np.arange(-0.55, 0.56, 0.1)
    gx, gy = (a.ravel() for a in np.meshgrid(g, g))
    pts = np.stack([gx + rng.uniform(-0.025, 0.025, gx.size), gy + rng.uniform(-0.025, 0.025, gx.size),
                    np.full(gx.size, 2.0)], axis=1).astype(np.float32)
    cols = rng.uniform(0, 1, pts.shape).astype(np.float32)
    radius = 0.07
    K = np.array([[400.0, 0, 127.5], [0, 400.0, 121.0], [0, 0, 1]])
    view = renderer.render(pts, cols, np.full(len(pts), radius, np.float32), K, np.eye(4), size=(256, 240))
    assert view.point_id.shape == (240, 256) and view.point_id.dtype == np.int32
    uv, _ = cv2.projectPoints(pts.astype(np.float64), np.zeros(3), np.zeros(3), K, None)
    uv = uv.reshape(-1, 2)
    rows, cols_ = np.mgrid[0:240, 0:256]
    d = np.hypot(cols_[..., None] - uv[:, 0], rows[..., None] - uv[:, 1])  # (H, W, N) [px]
    r_px = radius * 400.0 / 2.0
    d_cov = np.where(d < r_px, d, np.inf)
    order = np.sort(d_cov, axis=-1)
    expected = np.where(np.isfinite(order[..., 0]), np.argmin(d_cov, axis=-1), -1)
    # leave out pixels on a tie (a Voronoi edge) or on a disk's rim, where float rounding decides
    with np.errstate(invalid="ignore"):
        gap = np.where(np.isfinite(order[..., 0]), order[..., 1] - order[..., 0], np.inf)
    clear = (gap > 1e-2) & (np.abs(d - r_px).min(axis=-1) > 1e-2)
    assert clear.mean() > 0.97
    np.testing.assert_array_equal(view.point_id[clear], expected[clear])
    assert (expected == -1).any() and (view.point_id == -1).any()  # there are gaps between the disks
    hit = view.point_id >= 0
    np.testing.assert_array_equal(view.color[hit], cols[view.point_id[hit]])
    assert (view.color[~hit] == 0).all() and (view.depth[~hit] == 0).all()
    np.testing.assert_allclose(view.depth[hit], 2.0, rtol=1e-6)
    assert view.size == (256, 240)
    np.testing.assert_array_equal(view.K, K)


@pytest.mark.gl
@pytest.mark.parametrize("near_first", [True, False])
def test_depth_test_nearer_plane_wins(renderer, near_first):
    rng = np.random.default_rng(2)
    g = np.arange(-1.5, 1.5, 3.0 / 77)[:77]  # jittered grids (voxel-fused clouds are): Poisson ones leave ~2 % holes
    gx, gy = (a.ravel() for a in np.meshgrid(g, g))
    planes = []
    for z in (1.5, 2.5):
        xy = np.c_[gx, gy] + rng.uniform(-0.01, 0.01, (gx.size, 2))
        planes.append(np.c_[xy, np.full(len(xy), z)])
    pts = np.concatenate(planes if near_first else planes[::-1]).astype(np.float32)
    near_ids = np.arange(5929) if near_first else np.arange(5929, 11858)
    cols = np.zeros_like(pts)
    cols[near_ids] = (1.0, 0.0, 0.0)
    cols[np.setdiff1d(np.arange(11858), near_ids)] = (0.0, 0.0, 1.0)
    K, pose = camera_looking_at((0, 0, 0), (0, 0, 1), fov_deg=60, size=(200, 200))
    view = renderer.render(pts, cols, point_spacing(pts), K, pose, size=(200, 200))
    assert view.mask.mean() > 0.99
    assert np.isin(view.point_id[view.mask], near_ids).all()
    assert (view.color[view.mask] == (1.0, 0.0, 0.0)).all()
    assert np.abs(view.depth[view.mask] - 1.5).max() < 1e-5


@pytest.mark.gl
def test_dense_room_has_no_holes(renderer):
    p, _, c = room_cloud(step=0.03)
    s = point_spacing(p)
    views = renderer.render_cubemap(p, c, s, ROOM / 2 + (0.3, -0.2, 0.1), face_size=256)
    assert len(views) == 6
    for v in views:
        assert v.mask.mean() > 0.98, v.mask.mean()
        hit = v.mask
        # ids map back to the points: re-project them with the view's camera and compare pixels
        cam = (p[v.point_id[hit]] - v.world_from_camera[:3, 3]) @ v.world_from_camera[:3, :3]
        uv = cam @ v.K.T
        uv = uv[:, :2] / uv[:, 2:]
        rows, cols = np.nonzero(hit)
        err = np.hypot(uv[:, 0] - cols, uv[:, 1] - rows)
        radius_px = s[v.point_id[hit]] * v.K[0, 0] / cam[:, 2]
        assert (err <= np.maximum(radius_px, 0.71) + 1e-3).all()
        np.testing.assert_allclose(v.depth[hit], cam[:, 2], rtol=1e-5)
    p_pinhole = ROOM / 2
    K, pose = camera_looking_at(p_pinhole, (4.0, 2.0, 1.0), fov_deg=100, size=(320, 240))
    v = renderer.render(p, c, s, K, pose, size=(320, 240))
    assert v.mask.mean() > 0.98


@pytest.mark.gl
def test_cube_faces_follow_the_cube_convention(renderer):
    centre = np.array([0.2, -0.1, 0.3])
    dirs = np.array([[1, 0.2, -0.3], [-1, 0.4, 0.1], [0.3, 1, 0.2], [0.1, -1, -0.5], [0.2, 0.3, 1], [-0.6, 0.1, -1]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    pts = (centre + 2.0 * dirs).astype(np.float32)
    views = renderer.render_cubemap(pts, np.ones_like(pts), np.full(6, 0.002, np.float32), centre, face_size=64)
    face, row, col = texel_from_direction(dirs, 64)
    for i in range(6):
        assert views[face[i]].point_id[int(np.round(row[i])), int(np.round(col[i]))] == i


def blob_room():
    """A room with two bright blobs (a window on the x = 4 wall behind a pillar, a lamp on the ceiling)."""
    rng = np.random.default_rng(3)
    p, n, c = room_cloud(step=0.03, seed=3)
    pillar, pn = box_surface((3.2, 1.3, 0.0), (3.5, 1.7, 2.5), 0.03, rng)
    pn = -pn  # outward
    p, n = np.concatenate([p, pillar]), np.concatenate([n, pn])
    c = np.concatenate([c, rng.uniform(0.2, 0.6, (len(pillar), 3)).astype(np.float32)])
    window = (np.abs(p[:, 0] - 4.0) < 1e-6) & (np.hypot(p[:, 1] - 1.5, p[:, 2] - 1.4) < 0.35)
    lamp = (np.abs(p[:, 2] - 2.5) < 1e-6) & (np.hypot(p[:, 0] - 1.0, p[:, 1] - 2.0) < 0.2)
    c[window] = 0.97
    c[lamp] = (1.0, 0.95, 0.9)
    return p, n, c, np.flatnonzero(window), np.flatnonzero(lamp)


def test_saturated_clusters_find_the_blobs():
    p, n, c, window, lamp = blob_room()
    clusters = saturated_clusters(p, c, normals=n)
    assert len(clusters) == 2
    assert set(clusters[0].indices) == set(window) and set(clusters[1].indices) == set(lamp)
    np.testing.assert_allclose(clusters[0].centre, (4.0, 1.5, 1.4), atol=0.02)
    assert abs(abs(clusters[0].normal[0]) - 1) < 1e-6 and abs(abs(clusters[1].normal[2]) - 1) < 1e-6
    assert clusters[0].radius == pytest.approx(0.35, abs=0.03)
    u8 = np.round(c * 255).astype(np.uint8)
    assert [len(x.indices) for x in saturated_clusters(p, u8)] == [len(window), len(lamp)]
    dark = np.minimum(c, 0.8)
    assert saturated_clusters(p, dark) == [] and place_views(p, dark, 3) == []


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.parametrize("with_normals", [True, False])
def test_place_views_see_each_blob(renderer, with_normals):
    p, n, c, window, lamp = blob_room()
    views = place_views(p, c, 4, normals=n if with_normals else None)
    assert len(views) == 2
    tree_d = np.linalg.norm(p[None] - np.array([v[0] for v in views])[:, None], axis=2).min(axis=1)
    assert (tree_d > 0.05).all()  # in free space, not inside a wall or the pillar
    s = point_spacing(p)
    for (pos, look), blob in zip(views, (window, lamp)):
        assert ((pos > 0) & (pos < ROOM)).all()
        np.testing.assert_allclose(look, p[blob].mean(axis=0), atol=1e-5)
        K, pose = camera_looking_at(pos, look, fov_deg=90, size=(256, 256))
        v = renderer.render(p, c, s, K, pose, size=(256, 256))
        seen = np.isin(blob, v.point_id)
        assert seen.mean() > 0.5, seen.mean()
    # the pillar hides the window from straight in front (x = 3.0 .. 3.2): the view is not there
    wpos = views[0][0]
    assert not (wpos[0] < 3.2 and 1.3 < wpos[1] < 1.7)


def test_camera_looking_at_and_explicit_views():
    K, pose = camera_looking_at((1, 2, 1), (3, 2, 1), fov_deg=90, size=(200, 100))
    np.testing.assert_allclose(K, [[100, 0, 99.5], [0, 100, 49.5], [0, 0, 1]])
    np.testing.assert_allclose(pose[:3, :3], [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-12)
    assert np.linalg.det(pose[:3, :3]) == pytest.approx(1.0)
    _, down = camera_looking_at((0, 0, 2), (0, 0, 0))
    np.testing.assert_allclose(down[:3, 2], (0, 0, -1))
    views = views_from_positions([[1, 1, 1], [2, 2, 2]], [[0, 0, 0], [3, 3, 3]])
    assert len(views) == 2 and np.allclose(views[1][1], 3)
    with pytest.raises(HdrError, match="look_ats"):
        views_from_positions([[1, 1, 1]], [[0, 0, 0], [1, 2, 3]])


@pytest.mark.parametrize("points, colors, spacing, word", [
    (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), "points is empty"),
    (np.array([[0, 0, np.nan]]), np.zeros((1, 3)), np.ones(1), "points has non-finite"),
    (np.zeros((4, 2)), np.zeros((4, 3)), np.ones(4), "points must be"),
    (np.zeros((4, 3)), np.zeros((4, 4)), np.ones(4), "colors must be"),
    (np.zeros((4, 3)), np.zeros((3, 3)), np.ones(4), "colors must be"),
    (np.zeros((4, 3)), np.zeros((4, 3)), np.ones(3), "spacing must be"),
    (np.zeros((4, 3)), np.zeros((4, 3)), np.zeros(4), "spacing must be"),
])
def test_bad_inputs_name_the_argument(points, colors, spacing, word):
    with pytest.raises(HdrError, match=word):
        check_cloud(points, colors, spacing, "render")
    if "spacing" not in word:
        with pytest.raises(HdrError, match=word.replace("must be", "")):
            place_views(points, colors, 1)
        if "colors" not in word:
            with pytest.raises(HdrError, match=word.replace("must be", "")):
                point_spacing(points)


@pytest.mark.gl
def test_bad_camera_and_size(renderer):
    p = np.zeros((2, 3), np.float32) + (0, 0, 1)
    with pytest.raises(HdrError, match="K must be"):
        renderer.render(p, p, np.ones(2), np.eye(3) * 0, np.eye(4), size=(8, 8))
    with pytest.raises(HdrError, match="world_from_camera"):
        renderer.render(p, p, np.ones(2), np.eye(3), np.eye(4) * 2, size=(8, 8))
    with pytest.raises(HdrError, match="size"):
        renderer.render(p, p, np.ones(2), np.eye(3), np.eye(4), size=(0, 8))
    with pytest.raises(HdrError, match="points is empty"):
        renderer.render(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.eye(3), np.eye(4), size=(8, 8))
    with pytest.raises(HdrError, match="colors must be"):
        renderer.render(p, p[:, :2], np.ones(2), np.eye(3), np.eye(4), size=(8, 8))
    with pytest.raises(HdrError, match="position"):
        renderer.render_cubemap(p, p, np.ones(2), (0, np.nan, 0))
