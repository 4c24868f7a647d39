"""GPU 360° IBL renderer (probeless.pano.render) against numpy references, and the pano_compositor node."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.ibl.objects import object_from_dict
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.pano.compositor import PanoCompositor
from probeless.pano import glossy
from probeless.pano.equirect import pixel_directions
from probeless.pano.render import PanoRenderer
from probeless.pano.view import intrinsics, look_rotation, view_equirect
from probeless.runtime.testing import run_node

pytestmark = [pytest.mark.gl]

W, H = 120, 90
CENTRE, RADIUS = np.array([3.0, 0.0, 0.0]), 0.8


@pytest.fixture(scope="module")
def gl():
    r = PanoRenderer([])
    yield r.ctx
    r.release()


def forward_pose(yaw=0.0, pitch=0.0):
    pose = np.eye(4)
    pose[:3, :3] = look_rotation(yaw, pitch)
    return pose


def sphere(material, centre=CENTRE, radius=RADIUS, oid="s"):
    return object_from_dict({"id": oid, "mesh": "sphere", "position": list(centre), "radius": radius,
                             "material": material})


def render(gl, objects, hdr, diffuse, fov=60.0, pose=None):
    r = PanoRenderer(objects, ctx=gl)
    r.set_environment(hdr, diffuse)
    out = r.render(fov, forward_pose() if pose is None else pose, W, H)
    r.release()
    return out


def analytic_sphere(fov=60.0):
    """Per pixel: ray, hit mask, unit normal and mirror direction of the exact sphere (camera at 0, along +x)."""
    K = intrinsics(fov, W, H)
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(K).T @ look_rotation(0.0, 0.0).T
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    b = rays @ CENTRE
    disc = b * b - (CENTRE @ CENTRE - RADIUS ** 2)
    hit = disc > 0
    normal = (rays * (b - np.sqrt(np.maximum(disc, 0)))[..., None] - CENTRE) / RADIUS
    refl = rays - 2 * (rays * normal).sum(-1, keepdims=True) * normal
    facing = -(rays * normal).sum(-1)
    return rays, hit & (facing > 0.5), normal, refl   # away from the silhouette (grazing reflections)


def smooth_env(h=64):
    d = pixel_directions(2 * h, h)
    blob = np.exp((d @ [0.6, 0.0, 0.8] - 1) / 0.02)
    return np.stack([1 + 0.8 * d[..., 0], 1 + 0.8 * d[..., 1] + 2 * blob, 1 + 0.8 * d[..., 2]], -1).astype(np.float32)


@pytest.mark.graph
def test_silhouette_matches_the_exact_sphere(gl):
    _, mask = render(gl, [sphere({"type": "mirror"})], smooth_env(), np.ones((8, 16, 3), np.float32))
    K = intrinsics(60.0, W, H)
    v, u = np.mgrid[0:H, 0:W]
    rays = np.stack([np.ones_like(u, float), -(u - K[0, 2]) / K[0, 0], -(v - K[1, 2]) / K[1, 1]], -1)
    angle = np.arccos(rays[..., 0] / np.linalg.norm(rays, axis=-1))
    inside = angle < np.arcsin(RADIUS / 3.0) - 0.01
    outside = angle > np.arcsin(RADIUS / 3.0) + 0.01
    assert mask[inside].all() and not mask[outside].any() and inside.sum() > 500


@pytest.mark.graph
def test_mirror_sphere_reflects_the_frame_like_numpy(gl):
    env = smooth_env()
    color, mask = render(gl, [sphere({"type": "mirror", "colour": [1.0, 0.5, 0.25]})], env,
                         np.ones((8, 16, 3), np.float32))
    _, sel, _, refl = analytic_sphere()
    ref = glossy.mirror(env, refl[sel]) * [1.0, 0.5, 0.25]
    assert mask[sel].all()
    rel = np.abs(color[sel] - ref) / ref
    assert rel.max() < 0.02 and rel.mean() < 0.002
    flipped = glossy.mirror(env, refl[sel] * [1, -1, 1]) * [1.0, 0.5, 0.25]   # a u-flip would be seen
    assert (np.abs(flipped - ref) / ref).mean() > 20 * rel.mean()


@pytest.mark.graph
@pytest.mark.parametrize("roughness", [0.05, 0.2, 0.5])
def test_glossy_sphere_matches_numpy_ring_sampling(gl, roughness):
    # white noise: every mip level differs, so a wrong level, filter or pattern shows
    env = (0.2 + 2 * np.random.default_rng(0).random((128, 256, 3))).astype(np.float32)
    color, _ = render(gl, [sphere({"type": "metal", "colour": [1, 1, 1], "roughness": roughness})], env,
                      np.ones((8, 16, 3), np.float32))
    _, sel, _, refl = analytic_sphere()
    levels = glossy.mip_levels(env)
    ref = glossy.glossy_ring(levels, refl[sel], roughness)
    rel = np.abs(color[sel] - ref) / ref
    other = glossy.glossy_ring(levels, refl[sel], roughness * 1.5)
    assert np.median(rel) < 0.003 and np.percentile(rel, 90) < 0.01
    assert np.median(np.abs(other - ref) / ref) > 2 * np.median(rel)


@pytest.mark.graph
def test_lod_bias_reaches_the_ring_pattern(gl):
    env = (0.2 + 2 * np.random.default_rng(1).random((128, 256, 3))).astype(np.float32)
    r = PanoRenderer([sphere({"type": "metal", "colour": [1, 1, 1], "roughness": 0.2})], ctx=gl, lod_bias=-1.0)
    r.set_environment(env, np.ones((8, 16, 3), np.float32))
    color, _ = r.render(60.0, forward_pose(), W, H)
    r.release()
    _, sel, _, refl = analytic_sphere()
    levels = glossy.mip_levels(env)
    pattern = glossy.ring_pattern(0.2, env.shape[0], lod_bias=-1.0)
    ref = glossy.glossy_ring(levels, refl[sel], 0.2, pattern)
    paper = glossy.glossy_ring(levels, refl[sel], 0.2)
    rel = np.abs(color[sel] - ref) / ref
    assert np.median(rel) < 0.003 and np.median(np.abs(paper - ref) / ref) > 3 * np.median(rel)


@pytest.mark.graph
@pytest.mark.parametrize("sun_az", [150.0, 180.0, 215.0])
def test_objects_follow_a_moving_sun(gl, sun_az):
    """A sun moving over the sky of an LDR panorama, through the paper's ITMO and Algorithm 1: the diffuse
    sphere's brightest point turns with the sun's azimuth, and the side facing away is much darker."""
    from probeless.pano.diffuse import diffuse_map
    from probeless.pano.itmo import paper_itmo

    el = np.radians(30.0)
    sun = np.array([np.cos(el) * np.cos(np.radians(sun_az)), np.cos(el) * np.sin(np.radians(sun_az)), np.sin(el)])
    d = pixel_directions(256, 128)
    sky = np.where(d[..., 2:] > 0, [0.05, 0.07, 0.1], [0.04, 0.035, 0.03])  # a dim sky: the sun dominates
    ldr = np.clip(sky + np.exp((d @ sun - 1) / 0.02)[..., None], 0, 1)
    hdr = paper_itmo(np.round(ldr * 255) / 255)
    color, _ = render(gl, [sphere({"type": "diffuse", "albedo": [0.8, 0.8, 0.8]})], hdr, diffuse_map(hdr, (32, 16)))
    _, sel, normal, _ = analytic_sphere()
    lum = color @ [0.3, 0.59, 0.11]
    k = np.argmax(np.where(sel, lum, -1))
    n = normal.reshape(-1, 3)[k]  # the sky is the same all around: the peak's azimuth is the sun's
    assert abs((np.degrees(np.arctan2(n[1], n[0])) - sun_az + 180) % 360 - 180) < 10 and n[2] > 0
    opposite = np.argmin(np.where(sel, normal @ sun, 2))
    assert lum.reshape(-1)[k] > 2 * lum.reshape(-1)[opposite]


@pytest.mark.graph
def test_diffuse_sphere_is_albedo_times_the_bilinear_diffuse_map(gl):
    d = pixel_directions(32, 16)
    diffuse = np.stack([0.5 + 0.4 * d[..., 0], 0.5 + 0.4 * d[..., 1], 0.6 + 0.3 * d[..., 2]], -1).astype(np.float32)
    albedo = np.array([0.5, 0.7, 0.9])
    color, _ = render(gl, [sphere({"type": "diffuse", "albedo": list(albedo)})], smooth_env(), diffuse)
    _, sel, normal, _ = analytic_sphere()
    ref = albedo * glossy.sample_equirect([diffuse], normal[sel], 0.0)
    np.testing.assert_allclose(color[sel], ref, rtol=0.01)


def fresnel(cos_i, eta):
    sin_t2 = (1 - cos_i ** 2) / eta ** 2
    cos_t = np.sqrt(np.maximum(1 - sin_t2, 0))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(sin_t2 >= 1, 1.0, 0.5 * (rs ** 2 + rp ** 2))


@pytest.mark.graph
def test_glass_sphere_mixes_refraction_and_reflection_by_fresnel(gl):
    env = smooth_env()
    color, _ = render(gl, [sphere({"type": "glass", "ior": 1.5})], env, np.ones((8, 16, 3), np.float32))
    rays, sel, normal, refl = analytic_sphere()
    i, n = rays[sel], normal[sel]
    cos_i = -(i * n).sum(-1)
    eta = 1 / 1.5   # Snell's law: t = eta i + (eta cos_i - cos_t) n
    cos_t = np.sqrt(1 - eta ** 2 * (1 - cos_i ** 2))
    t = eta * i + (eta * cos_i - cos_t)[:, None] * n
    f = fresnel(cos_i, 1.5)[:, None]
    ref = (1 - f) * glossy.mirror(env, t) + f * glossy.mirror(env, refl[sel])
    rel = np.abs(color[sel] - ref) / ref
    assert rel.max() < 0.03 and rel.mean() < 0.003


@pytest.mark.parametrize("material,gain", [
    ({"type": "mirror", "colour": [0.9, 0.8, 0.7]}, [0.9, 0.8, 0.7]),
    ({"type": "metal", "colour": [1, 1, 1], "roughness": 0.3}, [1, 1, 1]),
    ({"type": "diffuse", "albedo": [0.2, 0.4, 0.6]}, [0.2, 0.4, 0.6]),
    ({"type": "glass", "ior": 1.33, "tint": [1, 0.9, 0.8]}, [1, 0.9, 0.8]),
    ({"type": "mix", "layers": [{"weight": 0.6, "type": "diffuse", "albedo": [1, 1, 1]},
                                {"weight": 0.4, "type": "metal", "colour": [1, 1, 1], "roughness": 0.1}]}, [1, 1, 1]),
])
@pytest.mark.graph
def test_a_constant_environment_gives_constant_shading(gl, material, gain):
    c = np.array([0.7, 1.3, 2.1], np.float32)
    hdr = np.broadcast_to(c, (64, 128, 3)).copy()
    diffuse = np.broadcast_to(c, (16, 32, 3)).copy()   # the diffuse map of a constant frame is the constant
    color, mask = render(gl, [sphere(material)], hdr, diffuse)
    assert mask.sum() > 1000
    np.testing.assert_allclose(color[mask], np.broadcast_to(c * gain, (mask.sum(), 3)), rtol=2e-3)
    assert (color[~mask] == 0).all()


@pytest.mark.graph
def test_the_nearer_object_hides_the_farther_one(gl):
    hdr, diffuse = np.ones((32, 64, 3), np.float32), np.ones((8, 16, 3), np.float32)
    near = sphere({"type": "diffuse", "albedo": [1, 0, 0]}, centre=[2.0, 0.0, 0.0], radius=0.3, oid="near")
    far = sphere({"type": "diffuse", "albedo": [0, 1, 0]}, centre=[4.0, 0.0, 0.0], radius=1.0, oid="far")
    for objects in ([near, far], [far, near]):   # drawing order must not matter
        color, _ = render(gl, objects, hdr, diffuse)
        np.testing.assert_allclose(color[H // 2, W // 2], [1, 0, 0], atol=1e-3)
        np.testing.assert_allclose(color[H // 2, 5], [0, 0, 0], atol=1e-6)
        np.testing.assert_allclose(color[H // 2, W // 2 + 20], [0, 1, 0], atol=1e-3)


@pytest.mark.graph
def test_gpu_background_matches_view_equirect(gl):
    rng = np.random.default_rng(3)
    frame = (np.clip(smooth_env(64) * 80 + rng.normal(0, 20, (64, 128, 3)), 0, 255)).astype(np.uint8)
    r = PanoRenderer([], ctx=gl)
    r.set_background(frame)
    for yaw, pitch in ((0.0, 0.0), (123.0, 40.0), (300.0, -70.0)):
        pose = forward_pose(yaw, pitch)
        gpu = r.background(75.0, pose, W, H).astype(int)
        cpu = view_equirect(frame, pose, 75.0, W, H).astype(int)
        assert np.abs(gpu - cpu).max() <= 3 and np.abs(gpu - cpu).mean() < 0.5
    r.release()


def frames(n, h=32, shift_stamp=None):
    """(input, message) triples of n synthetic frames: a noisy LDR frame, its HDR and a flat diffuse map."""
    rng = np.random.default_rng(4)
    ldr = rng.integers(0, 256, (h, 2 * h, 3), dtype=np.uint8)
    out = []
    for k in range(n):
        hdr = Header(k * 40_000_000, "pano")
        other = Header(k * 40_000_000 + (shift_stamp or 0), "pano")
        out += [("image", Image(hdr, ldr, "rgb8")),
                ("hdr", Image(other, (ldr / 255.0 * 1.8).astype(np.float16), "rgbf16")),
                ("diffuse", Image(other, np.full((8, 16, 3), 0.5, np.float32), "rgbf32"))]
    return out, ldr


AHEAD = [{"id": "ball", "mesh": "sphere", "position": [3.0, 0.0, 0.0], "radius": 0.5,
          "material": {"type": "diffuse", "albedo": [1.0, 1.0, 1.0]}}]
STILL = {"yaw0_deg": 0.0, "yaw_deg_per_s": 0.0, "pitch_deg": 0.0, "pitch_amp_deg": 0.0}


@pytest.mark.graph
@pytest.mark.parametrize("background", ["remap", "gpu"])
def test_compositor_draws_objects_over_the_view_of_the_frame(background):
    msgs, ldr = frames(2)
    ctx = run_node(PanoCompositor, msgs, {"objects": AHEAD, "width": 64, "height": 48, "fov_deg": 60.0,
                                          "background": background, **STILL})
    out = ctx.outputs("image")
    assert [m.header.stamp_ns for m in out] == [0, 40_000_000]
    img = out[0].data
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    np.testing.assert_array_equal(img[24, 32], [128, 128, 128])   # 0.5 diffuse x albedo 1, direct encoding
    view = view_equirect(ldr, forward_pose(), 60.0, 64, 48).astype(int)
    tol = 0 if background == "remap" else 3
    assert np.abs(img[:, :10].astype(int) - view[:, :10]).max() <= tol   # the ball is only in the middle


@pytest.mark.graph
def test_compositor_stereo_is_side_by_side_with_parallax():
    msgs, _ = frames(1)
    ctx = run_node(PanoCompositor, msgs, {"objects": AHEAD, "mode": "stereo", "width": 40, "height": 50,
                                          "fov_deg": 60.0, "ipd_m": 0.5, **STILL})
    img = ctx.outputs("image")[0].data
    assert img.shape == (50, 80, 3)
    left, right = img[:, :40], img[:, 40:]
    ball = lambda eye: np.nonzero((eye[25] == 128).all(axis=-1))[0].mean()   # noqa: E731
    # the left eye sits to the left of the head, so it sees the ball further right
    assert ball(left) > ball(right) + 2


@pytest.mark.graph
def test_compositor_waits_for_matching_stamps():
    msgs, _ = frames(2, shift_stamp=1)
    ctx = run_node(PanoCompositor, msgs, {"objects": AHEAD, "width": 16, "height": 12})
    assert ctx.outputs("image") == []
