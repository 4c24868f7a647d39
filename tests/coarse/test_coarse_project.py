"""The CPU texturing projection (texel -> fisheye pixel) and bilinear sampling, against independent references."""

from __future__ import annotations

import cv2
import numpy as np

from probeless.cameras.base import camera_matrix
from probeless.cameras.omnidir import OmnidirModel
from probeless.coarse.project import project_texels, sample_image
from probeless.geom.rotation import transform_from_rpy


def _pose():
    """world_from_fisheye: a tilted camera at (1.2, 0.7, 1.5)."""
    return transform_from_rpy([1.2, 0.7, 1.5], [-100.0, 15.0, 30.0])


def _world(pose, cam_points):
    cam = np.asarray(cam_points, np.float64)
    return cam @ pose[:3, :3].T + pose[:3, 3]


def _direction(theta_deg, azimuth_deg, dist=2.0):
    t, a = np.radians(theta_deg), np.radians(azimuth_deg)
    return dist * np.array([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])


def test_hand_points_match_the_model_and_the_stereographic_formula():
    model = OmnidirModel.from_fov(512, 512, 185.0)  # xi = 1: r = f tan(theta / 2)
    pose = _pose()
    cam = np.array([[0.0, 0.0, 3.0], [0.4, -0.2, 1.0], [-1.0, 0.5, 0.3], _direction(60, 200), _direction(85, -45)])
    uv, in_view = project_texels(_world(pose, cam), model, pose, 185.0)
    ref_uv, ref_valid = model.project(cam)
    np.testing.assert_allclose(uv, ref_uv, atol=1e-9)
    assert in_view.all() and ref_valid.all()
    f, c = model.K[0, 0], model.K[0, 2]
    np.testing.assert_allclose(uv[0], [c, c], atol=1e-9)  # on the optical axis: the principal point
    theta = np.arccos(cam[3, 2] / np.linalg.norm(cam[3]))
    r = f * np.tan(theta / 2)
    az = np.radians(200)
    np.testing.assert_allclose(uv[3], [c + r * np.cos(az), c + r * np.sin(az)], atol=1e-9)
    # a distorted model goes through its own project()
    distorted = OmnidirModel(512, 512, model.K, 1.0, (0.02, -0.01, 0.001, 0.0005))
    uv, in_view = project_texels(_world(pose, cam), distorted, pose, 185.0)
    ref_uv, _ = distorted.project(cam)
    np.testing.assert_allclose(uv, ref_uv, atol=1e-9)
    assert in_view.all() and np.abs(ref_uv - model.project(cam)[0]).max() > 0.5


def test_field_of_view_boundary_and_image_bounds():
    fov = 185.0
    model = OmnidirModel.from_fov(512, 512, fov)
    pose = _pose()
    half = fov / 2
    # along the diagonal the image corners lie beyond the fov circle: only the fov test rejects them
    cam = np.array([_direction(half - 0.2, 45), _direction(half + 0.2, 45), _direction(half - 0.2, 0),
                    _direction(half + 0.2, 180), [0.0, 0.0, -1.0]])
    uv, in_view = project_texels(_world(pose, cam), model, pose, fov)
    assert in_view.tolist() == [True, False, True, False, False]
    assert model.in_image(uv[1:2])[0], "the point past the fov must still land on the image (corner)"
    # a narrower fov parameter cuts the same model tighter
    uv, in_view = project_texels(_world(pose, cam[:1]), model, pose, 150.0)
    assert not in_view[0]
    # a wide image: the fov circle overflows the short side, those pixels are off the image
    f = model.K[0, 0]
    wide = OmnidirModel(800, 300, camera_matrix(f, f, 399.5, 149.5), 1.0)
    cam2 = np.array([_direction(80, 90), _direction(80, 0), _direction(20, 90)])
    uv, in_view = project_texels(_world(pose, cam2), wide, pose, fov)
    assert uv[0, 1] > 299.5 and 0 <= uv[1, 0] <= 799.5
    assert in_view.tolist() == [False, True, True]


def test_sample_image_matches_cv2_remap_bilinear_replicate():
    rng = np.random.default_rng(3)
    h, w = 37, 53
    image = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    n = 100 * 100
    # on OpenCV's 1/32-pixel interpolation grid remap is exact; include the border and beyond it
    u = np.round(rng.uniform(-3.0, w + 2.0, n) * 32) / 32
    v = np.round(rng.uniform(-3.0, h + 2.0, n) * 32) / 32
    ours = sample_image(image, np.stack([u, v], axis=1))
    mx, my = u.reshape(100, 100).astype(np.float32), v.reshape(100, 100).astype(np.float32)
    ref = cv2.remap(image.astype(np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    assert ours.dtype == np.float32 and ours.shape == (n, 3)
    np.testing.assert_allclose(ours, ref.reshape(n, 3) / 255.0, atol=2e-6)
    ref8 = cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    assert np.abs(ours * 255.0 - ref8.reshape(n, 3)).max() <= 1.0  # fixed-point weights + rounding


def test_sample_image_pixel_centres_and_non_finite():
    image = np.zeros((4, 5, 3), np.uint8)
    image[2, 3] = (255, 100, 0)
    out = sample_image(image, np.array([[3.0, 2.0], [3.5, 2.0], [3.0, 2.5], [np.nan, 1.0]]))
    np.testing.assert_allclose(out[0] * 255, [255, 100, 0], atol=1e-4)
    np.testing.assert_allclose(out[1] * 255, [127.5, 50, 0], atol=1e-4)
    np.testing.assert_allclose(out[2] * 255, [127.5, 50, 0], atol=1e-4)
    assert np.isnan(out[3]).all()


# --- occlusion (paper §4.4) -------------------------------------------------------------------

def _crosses_any_edge(p: np.ndarray, q: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(K,) bool brute force: segment p -> q[k] properly crosses some floorplan edge (strict orientations)."""
    a, b = poly, np.roll(poly, -1, axis=0)

    def orient(o, x, y):  # sign of the cross product (x - o) x (y - o), broadcast (K, E)
        return np.sign((x[..., 0] - o[..., 0]) * (y[..., 1] - o[..., 1])
                       - (x[..., 1] - o[..., 1]) * (y[..., 0] - o[..., 0]))

    P, Q, A, B = p[None, None], q[:, None], a[None], b[None]
    crossing = (orient(P, Q, A) * orient(P, Q, B) < 0) & (orient(A, B, P) * orient(A, B, Q) < 0)
    return crossing.any(axis=1)


def _room_texels(path, size=256):
    from probeless.coarse.atlas import fit_atlas
    from probeless.coarse.texels import texel_map
    from probeless.scene.parse import load_scene

    scene = load_scene(path)
    layout = fit_atlas(scene.floorplan, scene.ceiling_height, size)
    tm = texel_map(layout)
    core = tm.core.ravel()
    return scene, layout, tm.position.reshape(-1, 3)[core], tm.normal.reshape(-1, 3)[core], tm.surface.ravel()[core]


def test_texels_behind_the_partition_are_occluded_like_brute_force():
    from probeless.coarse.occlusion import floor_points, texel_visible

    scene, layout, pos, nrm, surface = _room_texels("launch/scenes/partition_room.yaml")
    offset = 1.5 / layout.texels_per_m
    for viewpoint in (np.array([1.0, 1.0]), np.array([4.6, 0.7]), np.array([3.0, 3.5])):
        ours = texel_visible(pos, nrm, scene.floorplan, viewpoint, offset_m=offset)
        ref = ~_crosses_any_edge(viewpoint, floor_points(pos, nrm, offset), scene.floorplan)
        walls = surface < len(scene.floorplan)
        assert 0.05 < 1 - ref.mean() < 0.9, "the viewpoint must see part of the room and not all of it"
        assert (~ref[walls]).sum() > 500, "wall texels behind the partition must exist"
        assert np.sum(ours != ref) <= 5, f"{np.sum(ours != ref)} of {len(ref)} texels disagree at {viewpoint}"
    # from the left bay, the right bay's back wall segment behind the partition (x = 6 wall, low y) is hidden
    ours = texel_visible(pos, nrm, scene.floorplan, np.array([1.0, 1.0]), offset_m=offset)
    hidden = (pos[:, 0] > 5.99) & (pos[:, 1] < 0.5)
    assert hidden.sum() > 10 and not ours[hidden].any()


def test_l_shaped_room_occludes_and_convex_room_does_not():
    from probeless.coarse.occlusion import floor_points, texel_visible

    scene, layout, pos, nrm, _ = _room_texels("launch/scenes/l_shaped_lounge.yaml")
    offset = 1.5 / layout.texels_per_m
    viewpoint = np.array([5.0, 1.0])
    ours = texel_visible(pos, nrm, scene.floorplan, viewpoint, offset_m=offset)
    ref = ~_crosses_any_edge(viewpoint, floor_points(pos, nrm, offset), scene.floorplan)
    assert 0.05 < 1 - ref.mean() and np.sum(ours != ref) <= 5
    scene, layout, pos, nrm, _ = _room_texels("launch/scenes/convex_room.yaml", 128)
    assert texel_visible(pos, nrm, scene.floorplan, np.array([1.0, 1.0]), offset_m=0.01).all()
