"""The reference room, its cloud and the Mitsuba reference renderer, against analytic values."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from probeless.errors import PbgiError
from probeless.pbgi.reference import (
    bsdf_dict,
    material_spec,
    mitsuba_scene,
    pixel_rays,
    render_reference,
)
from probeless.pbgi.room import (
    Patch,
    ReferenceRoom,
    object_camera,
    radiance_at,
    reference_room,
    sample_cloud,
    uniform_room,
)
from probeless.scene.trajectory import look_at

mi = pytest.importorskip("mitsuba")


def _load(room, material, K, T, w, h, spp=4):
    from probeless.pbgi.reference import _mitsuba
    return _mitsuba().load_dict(mitsuba_scene(room, material, K, T, w, h, spp), parallel=False, optimize=False)


def _render(room, K, T, w, h, spp, material=("lambert", 0.5), seed=0):
    from probeless.pbgi.reference import _mitsuba
    scene = _load(room, material, K, T, w, h, spp)
    return np.array(_mitsuba().render(scene, spp=spp, seed=seed), np.float32)


def _square_patch(name, centre, normal, side, radiance):
    """A constant side x side patch centred on ``centre``, emitting along ``normal``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(n, [0, 0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0, 0])
    a /= np.linalg.norm(a)
    eu, ev = a * side, np.cross(n, a) * side  # eu x ev = side^2 n
    img = np.broadcast_to(np.asarray(radiance, np.float32), (4, 4, 3)).copy()
    return Patch(name, np.asarray(centre, float) - (eu + ev) / 2, eu, ev, img)


# --- room and cloud --------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["plain", "red_wall"])
def test_cloud_counts_normals_and_facing(name):
    room = reference_room(name)
    pts, cols, nrm = sample_cloud(room, spacing=0.05)
    expected = sum(max(1, round(np.linalg.norm(p.edge_u) / 0.05)) * max(1, round(np.linalg.norm(p.edge_v) / 0.05))
                   for p in room.all_patches)
    assert len(pts) == len(cols) == len(nrm) == expected
    assert pts.dtype == np.float64 and cols.dtype == np.float32 and nrm.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-12)
    assert np.all((pts >= -1e-9) & (pts <= room.size + 1e-9))
    # every point emits towards the sphere's side of its patch (inside the room, towards the object)
    assert np.all(np.sum((room.object_centre - pts) * nrm, axis=1) > 0)
    assert cols.min() >= 0 and cols.max() > 20  # HDR lamp
    area = sum(p.area for p in room.all_patches)
    assert len(sample_cloud(room)[0]) == pytest.approx(area / 0.01**2, rel=0.01)  # ~0.68 M points at 1 cm


def test_patches_tile_the_box_without_overlap():
    room = reference_room("plain")
    X, Y, Z = room.size
    assert sum(p.area for p in room.patches) == pytest.approx(2 * (X * Y + X * Z + Y * Z))
    pts = sample_cloud(room, spacing=0.02)[0]
    assert len(np.unique(np.round(pts, 6), axis=0)) == len(pts)


def test_jittered_cloud_stays_on_its_patches():
    room = reference_room("red_wall")
    a, ca, _ = sample_cloud(room, spacing=0.05)
    b, cb, _ = sample_cloud(room, spacing=0.05, seed=3, jitter=True)
    assert a.shape == b.shape and np.abs(a - b).max() <= 0.025 * np.sqrt(2) + 1e-9 and np.abs(a - b).max() > 0
    assert np.all((b >= -1e-9) & (b <= room.size + 1e-9))


def test_red_panel_is_30cm_from_the_sphere_and_faces_it():
    room = reference_room("red_wall")
    (panel,) = room.panels
    c, r = room.object_centre, room.object_radius
    gap = abs(np.dot(c - panel.origin, panel.normal)) - r
    assert gap == pytest.approx(0.30, abs=0.01)
    assert np.dot(c - panel.origin, panel.normal) > 0
    assert np.linalg.norm(panel.edge_u) == pytest.approx(1.0) and np.linalg.norm(panel.edge_v) == pytest.approx(1.0)
    assert abs(panel.normal[2]) < 1e-12  # vertical
    red = panel.radiance.reshape(-1, 3).mean(0)
    assert red[0] > 10 * red[1] and red[0] > 10 * red[2]
    assert not reference_room("plain").panels
    with pytest.raises(PbgiError):
        reference_room("nope")


def test_bilinear_lookup_hits_texel_centres_and_clamps():
    img = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    p = Patch("t", np.zeros(3), np.array([3.0, 0, 0]), np.array([0, 2.0, 0]), img)
    uv = np.array([[0.5 / 3, 0.25], [2.5 / 3, 0.75], [0.0, 0.0], [1.0, 1.0], [1 / 3, 0.25]])
    np.testing.assert_allclose(radiance_at(p, uv), [img[0, 0], img[1, 2], img[0, 0], img[1, 2],
                                                   (img[0, 0] + img[0, 1]) / 2])


# --- the emitters carry exactly the cloud's colours ------------------------------------------------


@pytest.mark.parametrize("name", ["red_wall"])
def test_emitter_radiance_equals_cloud_lookup_on_every_patch(name):
    """Mitsuba's emitter at a surface point returns the texel value sample_cloud gives it (orientation, filter)."""
    room = reference_room(name)
    K, T = object_camera(room, 8)
    scene = _load(room, ("lambert", 0.5), K, T, 8, 8)
    rng = np.random.default_rng(1)
    flipped_differs = 0
    for patch in room.all_patches:
        uv = rng.uniform(0.002, 0.998, (40, 2))
        want = radiance_at(patch, uv)
        for p, w in zip(patch.at(uv), want):
            si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*(p + 0.01 * patch.normal)), mi.Vector3f(*(-patch.normal))))
            assert si.is_valid()
            got = np.array(si.emitter(scene).eval(si))
            np.testing.assert_allclose(got, w, rtol=2e-4, atol=1e-6, err_msg=patch.name)
        flipped_differs += np.abs(radiance_at(patch, 1 - uv) - want).max() > 1e-2 * want.max()
    assert flipped_differs >= len(room.all_patches) - 2  # textures vary, so the test sees orientation
    # the back of a patch emits nothing (one-sided)
    panel = room.panels[0]
    p = panel.at(np.array([[0.5, 0.5]]))[0]
    si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*(p - 0.01 * panel.normal)), mi.Vector3f(*panel.normal)))
    assert np.all(np.array(si.emitter(scene).eval(si)) == 0)


@pytest.mark.parametrize("position, target", [((1.0, 1.9, 1.5), (0.0, 1.9, 1.5)),   # the window
                                              ((2.0, 2.5, 1.3), (2.0, 3.5, 1.3))])  # a textured wall
def test_rendered_walls_match_cloud_colours(position, target):
    from scipy.spatial import cKDTree

    room = reference_room("plain")
    pts, cols, _ = sample_cloud(room, spacing=0.01)
    w = h = 24
    T = look_at(np.array(position), np.array(target))
    K = np.array([[w / 2 / np.tan(np.radians(17)), 0, (w - 1) / 2], [0, w / 2 / np.tan(np.radians(17)), (h - 1) / 2],
                  [0, 0, 1]])
    image = _render(room, K, T, w, h, spp=8)
    o, d = pixel_rays(K, T, *np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float)))
    axis = np.argmax(np.abs(np.subtract(target, position)))
    hits = o + d * ((target[axis] - o[axis]) / d[..., axis])[..., None]
    _, idx = cKDTree(pts).query(hits.reshape(-1, 3))
    want = cols[idx].reshape(h, w, 3)
    rel = np.abs(image - want) / want
    assert np.median(rel) < 0.01 and rel.max() < 0.05


# --- camera -----------------------------------------------------------------------------------------


def test_camera_conversion_puts_a_point_where_the_pinhole_projects_it():
    w, h = 48, 32
    T = look_at(np.array([0.5, 0.4, 1.2]), np.array([2.0, 2.2, 0.7]))
    K = np.array([[40.0, 0, (w - 1) / 2], [0, 40.0, (h - 1) / 2], [0, 0, 1]])
    cam = T[:3, 3]
    targets = [T[:3, :3] @ np.array(x) + cam for x in ([0.3, -0.2, 2.0], [-0.45, 0.25, 2.5], [0.0, 0.0, 1.5])]
    patches = tuple(_square_patch(f"dot{i}", p, cam - p, 0.03, 50.0) for i, p in enumerate(targets))
    room = ReferenceRoom("dots", np.ones(3), patches, np.array([-50.0, -50.0, -50.0]), 0.1)
    image = _render(room, K, T, w, h, spp=128)[..., 0]
    for p in targets:
        x, y, z = (T[:3, :3].T @ (p - cam))
        u, v = K[0, 0] * x / z + K[0, 2], K[1, 1] * y / z + K[1, 2]
        iu, iv = int(round(u)), int(round(v))
        win = image[iv - 2:iv + 3, iu - 2:iu + 3]
        assert win.sum() > 0.5 * image.sum() / len(targets)
        gv, gu = np.mgrid[iv - 2:iv + 3, iu - 2:iu + 3]
        assert abs((win * gu).sum() / win.sum() - u) < 0.5 and abs((win * gv).sum() / win.sum() - v) < 0.5


def test_object_camera_frames_the_sphere_and_rejects_odd_intrinsics():
    room = reference_room("red_wall")
    for view in ("front", "side"):
        K, T = object_camera(room, (64, 48), view)
        x, y, z = T[:3, :3].T @ (room.object_centre - T[:3, 3])
        assert z > 0 and abs(K[0, 0] * x / z + K[0, 2] - 31.5) < 1e-9 and abs(K[1, 1] * y / z + K[1, 2] - 23.5) < 1e-9
        assert 2 * K[0, 0] * room.object_radius / z == pytest.approx(48 / 1.25, rel=0.02)
    K, T = object_camera(room, 64)
    off = K.copy()
    off[0, 2] += 3
    with pytest.raises(PbgiError, match="principal point"):
        mitsuba_scene(room, ("lambert", 0.5), off, T, 64, 64, 4)


def test_front_view_shows_the_red_panel_beside_the_sphere():
    room = reference_room("red_wall")
    K, T = object_camera(room, 32)
    image = _render(room, K, T, 32, 32, spp=4)
    right = image[12:20, 29:]
    assert np.all(right[..., 0] > 5 * right[..., 1])


# --- shading against analytic values ------------------------------------------------------------


def test_white_furnace_lambert_sphere_equals_albedo_times_radiance():
    room = uniform_room(reference_room("plain"), (0.7, 1.0, 1.3))
    K, T = object_camera(room, 32)
    image, mask = render_reference(room, ("lambert", (0.5, 0.6, 0.8)), K, T, 32, 32, spp=16)
    assert mask.sum() > 300
    want = np.array([0.35, 0.6, 1.04], np.float32)
    np.testing.assert_allclose(image[mask].mean(0), want, rtol=0.01)
    ratio = image[mask] / want
    assert ratio.std() < 0.1 and np.abs(ratio - 1).max() < 0.4  # Monte Carlo noise at 16 spp
    border = np.concatenate([image[0], image[-1], image[:, 0], image[:, -1]])  # the room seen directly
    np.testing.assert_allclose(border, np.broadcast_to([0.7, 1.0, 1.3], border.shape), rtol=1e-5)


def _irradiance(points, normals, patch, n=24):
    """Irradiance (N, 3) at sphere points from a constant patch, by midpoint quadrature over the patch."""
    g = (np.arange(n) + 0.5) / n
    q = patch.at(np.stack(np.meshgrid(g, g), -1).reshape(-1, 2))
    r = q[None] - points[:, None]
    d2 = np.sum(r * r, -1)
    cos_p = np.clip(np.sum(r * normals[:, None], -1), 0, None) / np.sqrt(d2)
    cos_q = np.clip(-r @ patch.normal, 0, None) / np.sqrt(d2)
    e = (cos_p * cos_q / d2).sum(1) * patch.area / n**2
    return e[:, None] * patch.radiance[0, 0]


def test_lambert_sphere_under_one_patch_matches_the_form_factor_integral():
    base = reference_room("plain")
    lamp = _square_patch("lamp", base.object_centre + [0.5, -0.3, 0.9], [-0.4, 0.2, -1.0], 0.5, (20.0, 15.0, 10.0))
    room = dataclasses.replace(base, patches=(lamp,))
    w = 32
    K, T = object_camera(room, w)
    albedo = 0.6
    image, mask = render_reference(room, ("lambert", albedo), K, T, w, w, spp=64)
    # the expected pixel: sphere radiance averaged over 3 x 3 sub-pixel rays (the box filter)
    s = np.arange(3) / 3 - 1 / 3
    vs, us = np.nonzero(mask)
    u = (us[:, None, None] + s[None, :, None]).repeat(3, 2).reshape(-1)
    v = (vs[:, None, None] + s[None, None, :]).repeat(3, 1).reshape(-1)
    o, d = pixel_rays(K, T, u, v)
    oc = o - room.object_centre
    b = d @ oc
    t = -b - np.sqrt(b * b - (oc @ oc - room.object_radius**2))
    p = o + t[:, None] * d
    want = (albedo / np.pi * _irradiance(p, (p - room.object_centre) / room.object_radius, lamp))
    want = want.reshape(-1, 9, 3).mean(1)
    got = image[mask]
    lit = want[:, 0] > 0.2 * want[:, 0].max()
    assert lit.sum() > 100
    assert np.abs(got[lit].mean(0) / want[lit].mean(0) - 1).max() < 0.01
    assert np.median(np.abs(got[lit] / want[lit] - 1)) < 0.05


def test_mask_excludes_edge_pixels():
    room = reference_room("plain")
    K, T = object_camera(room, 32)
    image, mask = render_reference(room, ("lambert", 0.5), K, T, 32, 32, spp=1)
    o, d = pixel_rays(K, T, *np.meshgrid(np.arange(33) - 0.5, np.arange(33) - 0.5))
    oc = o - room.object_centre
    b = d @ oc
    corner_hit = b * b - (oc @ oc - room.object_radius**2) > 0
    full = corner_hit[:-1, :-1] & corner_hit[1:, :-1] & corner_hit[:-1, 1:] & corner_hit[1:, 1:]
    np.testing.assert_array_equal(mask, full)
    o, d = pixel_rays(K, T, *np.meshgrid(np.arange(32.0), np.arange(32.0)))
    b = d @ (o - room.object_centre)
    centre_hit = b * b - (oc @ oc - room.object_radius**2) > 0
    assert centre_hit.sum() > mask.sum() > 0.6 * centre_hit.sum()


# --- materials, mesh, cache -------------------------------------------------------------------------


def test_material_specs_and_duck_typed_brdf():
    assert bsdf_dict(("lambert", 0.5))["type"] == "diffuse"
    g = bsdf_dict(("ggx", (0.9, 0.8, 0.7), 0.5))
    assert g["type"] == "roughconductor" and g["alpha"] == 0.25 and g["material"] == "none"
    assert g["specular_reflectance"]["value"] == [0.9, 0.8, 0.7] and g["distribution"] == "ggx"
    assert bsdf_dict(("ggx", 1.0, 0.0))["type"] == "conductor"
    assert bsdf_dict(("disney", 0.5, 0.3, 1.0))["metallic"] == 1.0
    brdf = SimpleNamespace(model="ggx", base_color=(0.9, 0.9, 0.9), roughness=0.3, metalness=1.0)
    assert material_spec(brdf) == ("ggx", (0.9, 0.9, 0.9), 0.3)
    for bad in [("phong", 1), ("ggx", 0.5), object(), SimpleNamespace(**vars(brdf), textured=True)]:
        with pytest.raises(PbgiError):
            material_spec(bad)


def test_mesh_object_matches_the_sphere():
    from probeless.ibl.mesh_io import place, uv_sphere

    room = reference_room("plain")
    mesh = place(*uv_sphere(1.0, 48, 96), room.object_centre, radius=room.object_radius)
    K, T = object_camera(room, 24)
    a, ma = render_reference(room, ("lambert", 0.7), K, T, 24, 24, spp=32)
    b, mb = render_reference(room, ("lambert", 0.7), K, T, 24, 24, spp=32, seed=1, mesh=mesh)
    both = ma & mb
    assert both.sum() > 0.9 * ma.sum()
    np.testing.assert_allclose(b[both].mean(0), a[both].mean(0), rtol=0.03)


def test_cache_returns_the_stored_render(tmp_path):
    room = reference_room("red_wall")
    K, T = object_camera(room, 16)
    a = render_reference(room, ("ggx", 0.9, 0.3), K, T, 16, 16, spp=2, cache=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 1
    fresh = render_reference(room, ("ggx", 0.9, 0.3), K, T, 16, 16, spp=2)
    np.testing.assert_array_equal(a[0], fresh[0])  # a seed gives the same image every time
    b = render_reference(room, ("ggx", 0.9, 0.3), K, T, 16, 16, spp=2, cache=tmp_path)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    render_reference(room, ("ggx", 0.9, 0.3), K, T, 16, 16, spp=2, seed=1, cache=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 2


def test_ggx_is_f0_times_d_times_separable_smith_g():
    """Mitsuba's roughconductor as built here: f0 D G1(wi) G1(wo) / (4 cos_i cos_o), alpha = roughness^2."""
    rough, f0 = 0.5, np.array([0.9, 0.6, 0.3])
    a2 = rough**4
    bsdf = mi.load_dict(bsdf_dict(("ggx", tuple(f0), rough)))
    si = mi.SurfaceInteraction3f()
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(si.n)

    def g1(w):
        return 2 / (1 + np.sqrt(1 + a2 * (1 - w[2] ** 2) / w[2] ** 2))
    for wi, wo in [((0.3, 0.1, 0.9), (-0.5, 0.2, 0.6)), ((0.7, 0.0, 0.3), (-0.6, -0.3, 0.5))]:
        wi, wo = np.array(wi) / np.linalg.norm(wi), np.array(wo) / np.linalg.norm(wo)
        h = (wi + wo) / np.linalg.norm(wi + wo)
        d = a2 / (np.pi * (h[2] ** 2 * (a2 - 1) + 1) ** 2)
        si.wi = mi.Vector3f(*wi)
        got = np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*wo)))  # includes cos_o
        np.testing.assert_allclose(got, f0 * d * g1(wi) * g1(wo) / (4 * wi[2]), rtol=1e-5)
