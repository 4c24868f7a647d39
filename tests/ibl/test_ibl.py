"""Image-based lighting of virtual objects (probeless.ibl) against analytic and brute-force references."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from locations import REPO

from probeless.color import from_srgb8
from probeless.envmap.sh import irradiance_from_sh, project_cubemap
from probeless.errors import SceneError
from probeless.geom.cube import sample_cubemap, texel_direction
from probeless.gl.context import create_context
from probeless.ibl.composite import composite, encode_srgb8
from probeless.ibl.lighting import Lighting
from probeless.ibl.materials import (
    Diffuse,
    Glass,
    Metal,
    Mirror,
    Mix,
    material_from_dict,
    shading,
)
from probeless.ibl.mesh_io import load_mesh, place, uv_sphere
from probeless.ibl.render import IblObject, IblRenderer
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.lighting import Cubemap, SHCoefficients
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.runtime.testing import run_node

W = H = 128
F = 200.0
K = np.array([[F, 0, (W - 1) / 2], [0, F, (H - 1) / 2], [0, 0, 1.0]])
CENTRE, R, DIST = np.array([0.0, 0.0, 1.0]), 0.5, 3.0


def camera_pose(eye, target) -> np.ndarray:
    """world_from_camera of an OpenCV camera (z forward, y down) at ``eye`` looking at ``target``, z up."""
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = eye
    return T


POSE = camera_pose(CENTRE + [DIST, 0, 0], CENTRE)


def cube(size: int, fn) -> np.ndarray:
    """(6, S, S, 3) float32 faces with texel value fn(unit direction (S, S, 3), face)."""
    r, c = np.mgrid[0:size, 0:size]
    return np.stack([fn(texel_direction(f, r, c, size), f) for f in range(6)]).astype(np.float32)


def pixel_rays(pose=POSE) -> np.ndarray:
    """(H, W, 3) unit world directions through the pixel centres."""
    v, u = np.mgrid[0:H, 0:W]
    d = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones((H, W))], axis=-1) @ pose[:3, :3].T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def sphere_hits(margin: float = 0.0, radius: float = R):
    """(hit mask, unit normals, view dirs) of the analytic sphere; ``margin`` drops rays this close to grazing."""
    d, o = pixel_rays(), POSE[:3, 3]
    oc = o - CENTRE
    b = d @ oc
    disc = b * b - (oc @ oc - radius * radius)
    hit = disc > (margin * radius) ** 2
    t = -b - np.sqrt(np.maximum(disc, 0))
    n = (o + t[..., None] * d - CENTRE) / R
    return hit, n, d


@pytest.fixture(scope="module")
def ctx():
    return create_context()


def render(ctx, material, faces, sh=None, mesh=None, levels=(), **obj):
    """Render one object (the sphere by default) under ``faces`` (SH projected from them unless given)."""
    mesh = mesh or place(*uv_sphere(), CENTRE, radius=R)
    obj.setdefault("contact_shadow", False)
    r = IblRenderer([IblObject("o", mesh, material, **obj)], ctx=ctx)
    r.set_lighting("o", Lighting(faces, project_cubemap(faces, 5) if sh is None else sh, levels))
    out = r.render(K, POSE, W, H)
    r.release()
    return out


@pytest.mark.gl
@pytest.mark.graph
def test_mirror_sphere_reflects_analytic_directions(ctx):
    faces = cube(64, lambda d, f: 0.5 + 0.5 * d)
    out = render(ctx, Mirror(), faces)
    hit, n, d = sphere_hits(margin=0.25)
    refl = d - 2 * np.sum(d * n, axis=-1, keepdims=True) * n
    expected = sample_cubemap(faces, refl[hit])
    err = np.abs(out.color[hit] - expected)
    assert err.mean() < 0.006 and err.max() < 0.03
    # the pixel facing the camera reflects back toward it (+x), grazing pixels reflect along the view ray
    np.testing.assert_allclose(out.color[H // 2, W // 2], [1.0, 0.5, 0.5], atol=0.02)
    rim = hit & ~sphere_hits(margin=0.45)[0]
    cos = np.sum(refl[rim] * d[rim], axis=-1)
    assert cos.min() > 0.5  # near-grazing reflections continue forward


@pytest.mark.graph
@pytest.mark.gl
def test_mask_and_depth_match_the_sphere_projection(ctx):
    out = render(ctx, Mirror(), cube(8, lambda d, f: np.ones_like(d)))
    rho = F * R / np.sqrt(DIST ** 2 - R ** 2)  # silhouette radius of the tangent cone [px]
    v, u = np.mgrid[0:H, 0:W]
    disc = np.hypot(u - K[0, 2], v - K[1, 2]) < rho
    iou = (out.mask & disc).sum() / (out.mask | disc).sum()
    assert iou > 0.97
    assert abs(out.mask.sum() / (np.pi * rho ** 2) - 1) < 0.03
    np.testing.assert_allclose(np.argwhere(out.mask).mean(axis=0), [K[1, 2], K[0, 2]], atol=0.3)
    assert out.depth[H // 2, W // 2] == pytest.approx(DIST - R, abs=0.01)
    assert np.all(np.isinf(out.depth[~out.mask]))


@pytest.mark.graph
@pytest.mark.gl
@pytest.mark.parametrize("shadowed", [False, True])
def test_diffuse_sphere_under_constant_light(ctx, shadowed):
    L, albedo = np.array([0.3, 0.5, 0.7]), np.array([0.8, 0.6, 0.4])
    out = render(ctx, Diffuse(tuple(albedo), shadowed=shadowed), cube(16, lambda d, f: np.broadcast_to(L, d.shape)))
    np.testing.assert_allclose(out.color[out.mask], np.broadcast_to(albedo * L, (out.mask.sum(), 3)),
                               rtol=0.01 if shadowed else 0.002)


def brute_irradiance(faces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Cosine-weighted sum over every cube texel, solid angle (2/S)^2 / (1 + a^2 + b^2)^1.5."""
    s = faces.shape[1]
    a = 2 * (np.arange(s) + 0.5) / s - 1
    omega = (2 / s) ** 2 / (1 + a[None, :] ** 2 + a[:, None] ** 2) ** 1.5
    r, c = np.mgrid[0:s, 0:s]
    dirs = np.stack([texel_direction(f, r, c, s) for f in range(6)]).reshape(-1, 3)
    w = np.clip(normals @ dirs.T, 0, None) * np.tile(omega.ravel(), 6)
    return w @ faces.reshape(-1, 3)


@pytest.mark.graph
@pytest.mark.gl
@pytest.mark.slow
def test_diffuse_irradiance_with_one_bright_face_matches_brute_force(ctx):
    faces = cube(32, lambda d, f: np.full_like(d, 4.0 if f == 0 else 0.2) * [1.0, 0.9, 0.8])
    out = render(ctx, Diffuse((1.0, 1.0, 1.0)), faces)
    hit, n, _ = sphere_hits(margin=0.2)
    expected = brute_irradiance(faces, n[hit]) / np.pi
    got = out.color[hit]
    assert np.abs(got - expected).max() / expected.max() < 0.015
    assert np.median(np.abs(got - expected) / expected) < 0.01


@pytest.mark.graph
@pytest.mark.gl
def test_shader_sh_basis_matches_numpy(ctx):
    rng = np.random.default_rng(3)
    coeffs = rng.normal(0, 0.05, (25, 3))
    coeffs[0] = 1.5
    out = render(ctx, Diffuse((1.0, 1.0, 1.0)), cube(8, lambda d, f: np.zeros_like(d)), sh=coeffs)
    hit, n, _ = sphere_hits(margin=0.2)
    np.testing.assert_allclose(out.color[hit], irradiance_from_sh(coeffs, n[hit]) / np.pi, atol=2e-3)


@pytest.mark.graph
@pytest.mark.gl
def test_glass_with_ior_one_shows_the_environment_straight_through(ctx):
    faces = cube(64, lambda d, f: 0.5 + 0.5 * d)
    out = render(ctx, Glass(ior=1.0), faces)
    hit, _, d = sphere_hits(margin=0.1)
    assert np.abs(out.color[hit] - sample_cubemap(faces, d[hit])).max() < 0.02
    # ior 1.5 at normal incidence: straight through, Fresnel R = 0.04 of the reflection back at the camera
    centre = render(ctx, Glass(ior=1.5), faces).color[H // 2, W // 2]
    np.testing.assert_allclose(centre, 0.96 * np.array([0.0, 0.5, 0.5]) + 0.04 * np.array([1.0, 0.5, 0.5]),
                               atol=0.01)


@pytest.mark.graph
@pytest.mark.gl
def test_roughness_blurs_monotonically(ctx):
    checker = cube(128, lambda d, f: np.repeat(((np.floor(4 * d[..., :2] + 8).sum(-1) % 2) * 0.8 + 0.1)[..., None],
                                               3, -1))
    hit, _, _ = sphere_hits(margin=0.3)
    var = [render(ctx, Metal((1, 1, 1), r), checker).color[hit, 0].var() for r in (0.0, 0.25, 0.5, 0.75)]
    assert all(a > b * 1.2 for a, b in itertools.pairwise(var)), var


@pytest.mark.graph
@pytest.mark.gl
def test_prefiltered_levels_are_used_for_metal(ctx):
    faces = cube(32, lambda d, f: np.full_like(d, 0.2))
    blurred = cube(32, lambda d, f: np.full_like(d, 0.6))
    out = render(ctx, Metal((1, 1, 1), 0.25), faces, levels=((0.5, blurred),))
    np.testing.assert_allclose(out.color[out.mask], 0.4, atol=1e-3)  # halfway between roughness 0 and 0.5


@pytest.mark.graph
@pytest.mark.gl
def test_mix_of_diffuse_and_mirror_adds_weighted_terms(ctx):
    L = np.array([0.4, 0.3, 0.2])
    mat = material_from_dict({"type": "mix", "layers": [{"weight": 0.5, "type": "diffuse", "albedo": [0.5, 0.5, 0.5]},
                                                        {"weight": 0.5, "type": "mirror"}]})
    out = render(ctx, mat, cube(16, lambda d, f: np.broadcast_to(L, d.shape)))
    np.testing.assert_allclose(out.color[out.mask], np.broadcast_to(0.25 * L + 0.5 * L, (out.mask.sum(), 3)),
                               rtol=0.01)


def test_material_errors():
    with pytest.raises(SceneError, match="unknown type"):
        material_from_dict({"type": "velvet"})
    with pytest.raises(SceneError, match="roughness"):
        material_from_dict({"type": "metal", "roughness": 2.0})
    with pytest.raises(SceneError, match="one specular roughness"):
        shading(Mix(((0.5, Metal(roughness=0.1)), (0.5, Metal(roughness=0.5)))))


FLOOR_POSE = camera_pose(np.array([2.2, 0.4, 2.2]), np.array([0.0, 0.0, 0.2]))


def floor_scene(ctx):
    """A diffuse sphere resting on z = 0 under a constant environment, seen obliquely from above."""
    mesh = place(*uv_sphere(rings=24, segments=48), [0.0, 0.0, R], radius=R)
    r = IblRenderer([IblObject("o", mesh, Diffuse(), contact_shadow=True)], ctx=ctx)
    faces = cube(16, lambda d, f: np.ones_like(d))
    r.set_lighting("o", Lighting(faces, project_cubemap(faces, 5)))
    out = r.render(K, FLOOR_POSE, W, H)
    r.release()
    return out


@pytest.mark.graph
@pytest.mark.gl
def test_contact_shadow_matches_the_sphere_form_factor(ctx):
    out = floor_scene(ctx)
    d = pixel_rays(FLOOR_POSE)
    t = -FLOOR_POSE[2, 3] / d[..., 2]
    p = FLOOR_POSE[:3, 3] + t[..., None] * d
    rho = np.hypot(p[..., 0], p[..., 1])
    near = (t > 0) & ~out.mask & (rho > 0.6 * R) & (rho < 2.5 * R)
    # unoccluded fraction of cosine-weighted uniform light under a sphere tangent to the plane: 1 - (R / D)^3
    expected = 1 - (R / np.hypot(rho[near], R)) ** 3
    assert near.sum() > 200
    assert np.abs(out.shadow[near, 0] - expected).max() < 0.03
    far = (t > 0) & (np.abs(p[..., :2]).max(axis=-1) > 4.2 * R)
    assert far.sum() > 100 and np.all(out.shadow[far] == 1.0)


@pytest.mark.graph
@pytest.mark.gl
def test_composite_darkens_only_the_shadow_and_draws_the_object(ctx):
    out = floor_scene(ctx)
    rgb = np.random.default_rng(0).integers(40, 220, (H, W, 3), dtype=np.uint8)
    comp = composite(rgb, out)
    untouched = ~out.mask & np.all(out.shadow == 1.0, axis=2)
    assert untouched.sum() > 1000 and np.array_equal(comp[untouched], rgb[untouched])
    np.testing.assert_array_equal(comp[out.mask], encode_srgb8(out.color[out.mask]))
    dark = ~out.mask & (out.shadow[..., 0] < 0.7)
    assert dark.sum() > 20
    assert np.all(from_srgb8(comp[dark]) < from_srgb8(rgb[dark]))


def test_mesh_loading_and_placement(tmp_path):
    v, f = load_mesh(REPO / "launch/scenes/meshes/teapot.obj")
    m = place(v, f, [1.0, 2.0, 0.0], radius=0.2, up="y", anchor="bottom", yaw_deg=30)
    assert m.radius == pytest.approx(0.2, rel=1e-6)
    assert m.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(m.centre[:2], [1.0, 2.0])
    lo, hi = v.min(0), v.max(0)  # the file is y-up: its y extent becomes the world height
    assert np.ptp(m.vertices[:, 2]) == pytest.approx(
        (hi[1] - lo[1]) * 0.2 / np.linalg.norm(v - (lo + hi) / 2, axis=1).max())
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1)[np.linalg.norm(m.normals, axis=1) > 0], 1.0,
                               atol=1e-9)
    import open3d as o3d

    sv, sf = uv_sphere(rings=8, segments=16)
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(sv), o3d.utility.Vector3iVector(sf))
    o3d.io.write_triangle_mesh(str(tmp_path / "s.ply"), mesh)
    pv, pf = load_mesh(tmp_path / "s.ply")
    np.testing.assert_allclose(pv, sv, atol=1e-6)
    np.testing.assert_array_equal(pf, sf)
    placed = place(pv, pf, [0, 0, 0], scale=2.0, up="z")
    np.testing.assert_allclose(np.sum(placed.normals * placed.vertices, axis=1) / 2.0, 1.0, atol=0.05)
    with pytest.raises(SceneError, match="not found"):
        load_mesh(tmp_path / "missing.obj")


@pytest.mark.gl
@pytest.mark.graph
def test_node_composites_a_mirror_sphere_lit_by_an_ldr_envmap():
    from probeless.nodes.ibl.compositor import IblCompositor

    faces = np.full((6, 16, 16, 3), 128, np.uint8)
    faces[4] = 200  # brighter ceiling
    env = Cubemap(Header(5, "world"), "ball", CENTRE, faces, linear=False)
    sh = SHCoefficients(Header(5, "world"), "ball", 5, project_cubemap(from_srgb8(faces), 5))
    rgb = np.random.default_rng(1).integers(0, 255, (H, W, 3), dtype=np.uint8)
    info = CameraInfo(Header(0, "rgb"), W, H, "pinhole", K)
    frames = [("rgb", Image(Header(t, "rgb"), rgb, "rgb8")) for t in (10, 20)]
    poses = [("pose", PoseStamped(Header(t, "world"), "rgb", POSE)) for t in (10, 30)]
    params = {"objects": [{"id": "ball", "mesh": "sphere", "position": CENTRE.tolist(), "radius": R,
                           "material": {"type": "mirror"}, "contact_shadow": False}]}
    ctx = run_node(IblCompositor, [("camera_info", info), ("envmap", env), ("sh", sh), frames[0], poses[0],
                                   frames[1], poses[1]], params)
    out = ctx.outputs("image")
    assert len(out) == 1 and out[0].header.stamp_ns == 10  # stamp 20 has no pose: not composited
    img = out[0].data
    hit, n, d = sphere_hits(margin=0.2)
    refl = d - 2 * np.sum(d * n, axis=-1, keepdims=True) * n
    # a mirror shows the LDR envmap's own sRGB codes (exposure 1), ceiling above, walls at the horizon
    up, side = hit & (refl[..., 2] > 0.95), hit & (np.abs(refl[..., 2]) < 0.3)
    assert up.sum() > 5 and side.sum() > 50
    assert np.all(np.abs(img[up].astype(int) - 200) <= 1) and np.all(np.abs(img[side].astype(int) - 128) <= 1)
    outside = ~sphere_hits(radius=1.05 * R)[0]
    np.testing.assert_array_equal(img[outside], rgb[outside])


@pytest.mark.gl
@pytest.mark.graph
def test_real_depth_hides_objects_behind_real_surfaces():
    from probeless.nodes.ibl.compositor import IblCompositor

    faces = np.full((6, 8, 8, 3), 90, np.uint8)
    env = Cubemap(Header(5, "world"), "ball", CENTRE, faces, linear=False)
    rgb = np.full((H, W, 3), 30, np.uint8)
    depth = np.zeros((H, W), np.uint16)
    depth[:, : W // 2] = 2000  # a real surface 2 m away on the left, nothing measured on the right
    params = {"objects": [{"id": "ball", "mesh": "sphere", "position": CENTRE.tolist(), "radius": R,
                           "material": {"type": "mirror"}, "contact_shadow": False}],
              "occlusion": True, "sh_from": "envmap"}
    ctx = run_node(IblCompositor, [("camera_info", CameraInfo(Header(0, "rgb"), W, H, "pinhole", K)),
                                   ("envmap", env), ("rgb", Image(Header(7, "rgb"), rgb, "rgb8")),
                                   ("depth", DepthImage(Header(7, "rgb"), depth, 1000.0)),
                                   ("pose", PoseStamped(Header(7, "world"), "rgb", POSE))], params)
    img = ctx.outputs("image")[0].data
    hit = sphere_hits(margin=0.1)[0]
    left, right = hit.copy(), hit.copy()
    left[:, W // 2:] = False
    right[:, : W // 2] = False
    assert np.all(img[left] == 30)                            # sphere (2.5 m) behind the real surface (2 m)
    assert np.all(np.abs(img[right].astype(int) - 90) <= 1)  # no depth: the object is drawn


def test_shadowed_prt_of_the_teapot_never_exceeds_the_unshadowed_transfer():
    from probeless.ibl.prt import transfer_vectors, unshadowed_transfer

    v, f = load_mesh(REPO / "launch/scenes/meshes/teapot.obj")
    m = place(v, f, [0, 0, 0], radius=0.2)
    sel = np.arange(0, len(m.vertices), 4)
    shadowed = transfer_vectors(m, m.vertices[sel], m.normals[sel], n_dirs=256)[:, 0]
    free = unshadowed_transfer(m.normals[sel], n_dirs=256)[:, 0]
    # 5-band projection of the cosine lobe, DC = pi * Y00 = sqrt(pi) / 2 (up to direction sampling)
    np.testing.assert_allclose(free, np.sqrt(np.pi) / 2, rtol=0.02)
    assert np.all(shadowed <= free + 1e-9)
    occluded = shadowed < 0.9 * free
    assert 0.05 < occluded.mean() < 0.8  # the spout, handle and lid rim shadow parts of the body
