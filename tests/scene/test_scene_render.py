"""SceneRenderer against analytic references: projection, depth, irradiance, shadows, cube convention."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from probeless.errors import SceneError
from probeless.geom.cube import sample_cubemap, texel_direction
from probeless.gl.context import create_context
from probeless.scene.geometry import AreaLight, SceneGeometry, Surface
from probeless.scene.render import SHADOW_OFFSET_M, SceneRenderer

pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope="module")
def ctx():
    context = create_context()
    yield context
    context.release()


def quad(name, center, half_u, half_v, color=(0.5, 0.5, 0.5), uv_scale=None, **kw) -> Surface:
    """Two triangles spanning center +- half_u +- half_v, normal along half_u x half_v."""
    c, hu, hv = (np.asarray(x, np.float64) for x in (center, half_u, half_v))
    n = np.cross(hu, hv)
    corners = np.array([c - hu - hv, c + hu - hv, c + hu + hv, c - hu + hv])[[0, 1, 2, 0, 2, 3]]
    uvs = corners[:, :2] / uv_scale if uv_scale else np.array([(0, 0), (1, 0), (1, 1), (0, 0), (1, 1), (0, 1)])
    return Surface(name, corners.astype("f4"), np.tile(n / np.linalg.norm(n), (6, 1)).astype("f4"),
                   uvs.astype("f4"), np.asarray(color, "f4"), **kw)


def box(name, center, size, color=(0.5, 0.5, 0.5), inward=False, **kw) -> list[Surface]:
    """The six faces of an axis-aligned box, normals outward (or inward for a room)."""
    c, h = np.asarray(center, np.float64), np.asarray(size, np.float64) / 2
    faces = []
    for axis in range(3):
        for sign in (1, -1):
            n = np.zeros(3)
            n[axis] = sign if not inward else -sign
            e1, e2 = np.eye(3)[(axis + 1) % 3] * h[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3] * h[(axis + 2) % 3]
            if np.dot(np.cross(e1, e2), n) < 0:
                e1 = -e1
            offset = np.zeros(3)
            offset[axis] = sign * h[axis]
            faces.append(quad(f"{name}{'+-'[sign < 0]}{'xyz'[axis]}", c + offset, e1, e2, color, **kw))
    return faces


def ceiling_light(center, half, radiance, ambient=(0, 0, 0)) -> AreaLight:
    return AreaLight("light", np.asarray(center, float), np.array([half, 0, 0.0]), np.array([0, -half, 0.0]),
                     np.array([0, 0, -1.0]), np.asarray(radiance, float), np.asarray(ambient, float))


def look_down(position) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])
    pose[:3, 3] = position
    return pose


def pixel_rays(K, width, height) -> np.ndarray:
    """(H, W, 3) camera-frame rays with z = 1 through integer pixel centres."""
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    return np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(K).T


def floor_hits(pose, K, width, height) -> np.ndarray:
    """World points where each pixel's ray meets the plane z = 0."""
    d = pixel_rays(K, width, height) @ pose[:3, :3].T
    t = -pose[2, 3] / d[..., 2]
    return pose[:3, 3] + t[..., None] * d


def reference_radiance(points, normal, albedo, light: AreaLight, n: int, visible=None) -> np.ndarray:
    """geometry.py's shading model evaluated in numpy at ``points`` (..., 3) for one light."""
    g = (np.arange(n) + 0.5) * (2.0 / n) - 1.0
    samples = (light.center + g[:, None, None] * light.half_u + g[None, :, None] * light.half_v).reshape(-1, 3)
    d = samples[None] - points.reshape(-1, 1, 3)
    d2 = np.sum(d * d, -1)
    dist = np.sqrt(d2)
    cos_l = np.maximum(-(d @ light.normal) / dist, 0)
    cos_s = np.maximum((d @ normal) / dist, 0)
    e = (light.area / n ** 2) * np.sum(cos_l * cos_s / np.maximum(d2, 1e-4), -1)
    if visible is not None:
        e = e * visible.reshape(-1)
    out = albedo / np.pi * light.radiance * e[:, None] + albedo * light.ambient
    return out.reshape(*points.shape[:-1], 3)


@pytest.mark.gl
@pytest.mark.graph
def test_depth_of_tilted_plane_is_analytic_z(ctx):
    n = np.array([0.3, -0.2, 1.0])
    n /= np.linalg.norm(n)
    p0 = np.array([0.1, 0.2, 0.0])
    hu = np.cross(n, [1.0, 0, 0]) * 10
    plane = quad("plane", p0, hu, np.cross(n, hu))
    pose = look_down([0.4, -0.3, 2.0])
    pose[:3, :3] = cv2.Rodrigues(np.array([0.2, -0.1, 0.3]))[0] @ pose[:3, :3]
    K = np.array([[150.0, 0, 80.3], [0, 140.0, 61.7], [0, 0, 1]])
    r = SceneRenderer(SceneGeometry((plane,), ()), ctx=ctx, shadow_size=16)
    radiance, depth = r.render_pinhole(pose, K, 160, 120, np.zeros(0))
    r.release()
    d = pixel_rays(K, 160, 120) @ pose[:3, :3].T
    z = np.dot(p0 - pose[:3, 3], n) / (d @ n)
    assert radiance.shape == (120, 160, 3) and depth.shape == (120, 160)
    np.testing.assert_allclose(depth, z, atol=1e-3)


@pytest.mark.graph
@pytest.mark.gl
def test_pixel_centres_follow_projectpoints(ctx):
    """Covered pixels are exactly those whose integer centres lie inside the projected quad."""
    c, hu, hv = np.array([0.3, 0.2, 0.0]), np.array([0.25, 0.05, 0.02]), np.array([-0.04, 0.2, 0.05])
    target = quad("target", c, hu, hv, emission=np.ones(3, "f4"))
    pose = look_down([0.0, 0.0, 1.5])
    pose[:3, :3] = cv2.Rodrigues(np.array([0.1, 0.15, 0.4]))[0] @ pose[:3, :3]
    K = np.array([[180.0, 0, 71.4], [0, 170.0, 52.6], [0, 0, 1]])
    r = SceneRenderer(SceneGeometry((target,), ()), ctx=ctx, shadow_size=16)
    radiance, depth = r.render_pinhole(pose, K, 150, 110, np.zeros(0))
    r.release()
    view = np.linalg.inv(pose)
    corners = np.array([c - hu - hv, c + hu - hv, c + hu + hv, c - hu + hv])
    img, _ = cv2.projectPoints(corners, cv2.Rodrigues(view[:3, :3])[0], view[:3, 3], K, None)
    poly = img.reshape(-1, 1, 2).astype(np.float32)
    signed = np.array([[cv2.pointPolygonTest(poly, (float(u), float(v)), True) for u in range(150)]
                       for v in range(110)])
    sure = np.abs(signed) > 0.02
    assert np.array_equal((radiance[..., 0] > 0)[sure], (signed > 0)[sure])
    assert (signed > 0).sum() > 500 and np.all(depth[radiance[..., 0] == 0] == 0)


@pytest.mark.graph
@pytest.mark.gl
def test_irradiance_from_area_light_matches_formula(ctx):
    h, albedo, radiance = 2.0, np.array([0.6, 0.5, 0.4]), np.array([50.0, 40.0, 30.0])
    light = ceiling_light([0, 0, h], 0.1, radiance)
    floor = quad("floor", [0, 0, 0], [10, 0, 0], [0, 10, 0], albedo)
    r = SceneRenderer(SceneGeometry((floor,), (light,)), ctx=ctx, shadow_size=128, light_samples=4)
    pose, K = look_down([0, 0, 1.5]), np.array([[100.0, 0, 100], [0, 100.0, 100], [0, 0, 1]])
    out, depth = r.render_pinhole(pose, K, 201, 201, np.ones(1))
    r.release()
    assert out[100, 100] == pytest.approx(albedo / np.pi * radiance * light.area / h ** 2, rel=0.01)
    pts = floor_hits(pose, K, 201, 201)
    np.testing.assert_allclose(out, reference_radiance(pts, np.array([0, 0, 1.0]), albedo, light, 4), rtol=5e-3)
    r2 = np.sum(pts[..., :2] ** 2, -1)
    cos4 = albedo / np.pi * radiance * light.area * h ** 2 / (h ** 2 + r2[..., None]) ** 2
    np.testing.assert_allclose(out, cos4, rtol=0.02)
    assert r2.max() > 4.0 and np.allclose(depth, 1.5, atol=1e-4)


def _occluded(points, origin, lo, hi) -> np.ndarray:
    """Whether the segment origin -> point crosses the box [lo, hi] (slab test)."""
    d = points - origin
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - origin) / d, (hi - origin) / d
    near = np.nanmax(np.minimum(t0, t1), -1)
    far = np.nanmin(np.maximum(t0, t1), -1)
    return (near <= far) & (far > 0) & (near < 1)


@pytest.mark.graph
@pytest.mark.gl
@pytest.mark.parametrize("pose", [look_down([0, 0, 0.5]), "grazing"])
def test_shadow_of_box_and_no_acne(ctx, pose):
    albedo, ambient = np.array([0.5, 0.5, 0.5]), np.array([0.02, 0.03, 0.04])
    light = ceiling_light([0, 0, 2.0], 0.05, [40.0, 40, 40], ambient)
    lo, hi = np.array([-0.1, -0.1, 0.9]), np.array([0.1, 0.1, 1.1])
    scene = SceneGeometry((quad("floor", [0, 0, 0], [12, 0, 0], [0, 12, 0], albedo),
                           *box("box", (lo + hi) / 2, hi - lo)), (light,))
    if isinstance(pose, str):  # camera low over the floor looking far along +x: grazing light angles
        pose = np.eye(4)
        pose[:3, :3] = np.column_stack([(0, -1.0, 0), (0, 0, -1.0), (1.0, 0, 0)])  # looking along +x
        pose[:3, :3] = pose[:3, :3] @ cv2.Rodrigues(np.array([-0.5, 0, 0]))[0]  # tilted 29 degrees down
        pose[:3, 3] = [-0.8, 0.3, 0.4]
    K = np.array([[60.0, 0, 80], [0, 60.0, 60], [0, 0, 1]])
    r = SceneRenderer(scene, ctx=ctx, shadow_size=256, light_samples=3)
    out, depth = r.render_pinhole(pose, K, 160, 120, np.ones(1))
    r.release()
    pts = floor_hits(pose, K, 160, 120)
    view = np.linalg.inv(pose)
    on_floor = (depth > 0) & (np.abs(depth - (pts @ view[2, :3] + view[2, 3])) < 1e-3)
    origin = light.center + SHADOW_OFFSET_M * light.normal
    grow, shrink = _occluded(pts, origin, lo - 0.03, hi + 0.03), _occluded(pts, origin, lo + 0.03, hi - 0.03)
    ref = reference_radiance(pts, np.array([0, 0, 1.0]), albedo, light, 3, visible=~grow)
    lit, shadowed = on_floor & ~grow, on_floor & shrink
    assert lit.sum() > 2000 and shadowed.sum() > 100
    np.testing.assert_allclose(out[lit], ref[lit], rtol=0.01)
    np.testing.assert_allclose(out[shadowed], np.broadcast_to(albedo * ambient, out[shadowed].shape), rtol=1e-4)


@pytest.mark.graph
@pytest.mark.gl
def test_cubemap_faces_follow_texel_direction(ctx):
    lo, hi = np.array([-2.0, -1.5, 0.0]), np.array([3.0, 2.0, 2.5])
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0, 1, 1], [1, 0, 1]], np.float32)
    # box() emits faces in the order +x, -x, +y, -y, +z, -z: give each its own emissive colour
    walls = [Surface(s.name, s.positions, s.normals, s.uvs, s.color, emission=colors[i])
             for i, s in enumerate(box("room", (lo + hi) / 2, hi - lo, inward=True))]
    eye, size = np.array([0.3, -0.2, 1.1]), 24
    r = SceneRenderer(SceneGeometry(tuple(walls), ()), ctx=ctx, shadow_size=16)
    faces = r.render_cubemap(eye, size, np.zeros(0))
    r.release()
    _, row, col = np.meshgrid(np.arange(6), np.arange(size), np.arange(size), indexing="ij")
    dirs = np.stack([texel_direction(i, row[i], col[i], size) for i in range(6)])
    with np.errstate(divide="ignore"):
        t = np.concatenate([(hi - eye) / dirs, (lo - eye) / dirs], -1)[..., [0, 3, 1, 4, 2, 5]]
    t[t <= 0] = np.inf
    order = np.sort(t, -1)
    wall = np.argmin(t, -1)
    sure = order[..., 1] > order[..., 0] * 1.05  # not within a few texels of a room edge
    assert sure.mean() > 0.8
    np.testing.assert_array_equal(faces[sure], colors[wall[sure]])
    for corner in [(0, 0), (0, size - 1), (size - 1, 0), (size - 1, size - 1)]:  # corners of every face
        assert np.array_equal(faces[:, corner[0], corner[1]][sure[:, corner[0], corner[1]]],
                              colors[wall[:, corner[0], corner[1]]][sure[:, corner[0], corner[1]]])
    np.testing.assert_array_equal(sample_cubemap(faces, dirs), faces)


def lit_room(texture=None):
    room = box("room", [0, 0, 1.25], [5, 4, 2.5], color=(0.7, 0.6, 0.5), inward=True)
    floor = quad("floor", [0, 0, 0.001], [2.5, 0, 0], [0, 2, 0], (0.8, 0.8, 0.8), uv_scale=0.5, texture=texture)
    light = ceiling_light([0.5, 0.3, 2.49], 0.3, [20.0, 18, 15], ambient=[0.05, 0.05, 0.05])
    panel = quad("panel", light.center, light.half_u, light.half_v, emission=light.radiance.astype("f4"),
                 light_index=0)
    return SceneGeometry((*room, floor, panel, *box("table", [-1, 0.5, 0.4], [0.8, 0.6, 0.8], (0.3, 0.5, 0.2))),
                         (light,))


@pytest.mark.graph
@pytest.mark.gl
def test_render_rays_matches_pinhole(ctx):
    checker = np.kron(np.indices((4, 4)).sum(0) % 2, np.ones((8, 8)))[..., None] * [0.7, 0.5, 0.3] + 0.2
    r = SceneRenderer(lit_room(checker.astype("f4")), ctx=ctx, shadow_size=256)
    pose = look_down([1.2, -0.8, 1.6])
    pose[:3, :3] = pose[:3, :3] @ cv2.Rodrigues(np.array([0.6, 0.3, 0.2]))[0]
    K = np.array([[90.0, 0, 64], [0, 90.0, 48], [0, 0, 1]])
    expected, _ = r.render_pinhole(pose, K, 128, 96, np.ones(1))
    rays = pixel_rays(K, 128, 96)
    rays = (rays / np.linalg.norm(rays, axis=-1, keepdims=True)).astype("f4")
    rays[0] = 0
    rays[1, :5] = np.nan
    out = r.render_rays(pose, rays, np.ones(1), cube_size=256)
    mirrored = r.render_rays(pose, np.ascontiguousarray(rays[:, ::-1]), np.ones(1), cube_size=256)
    r.release()
    assert np.all(out[0] == 0) and np.all(out[1, :5] == 0) and np.all(out[1, 5:] > 0)
    err = np.abs(out - expected)[2:]
    assert err.mean() < 0.03 * expected[2:].mean() and np.median(err) < 0.01 * expected[2:].mean()
    np.testing.assert_array_equal(mirrored, out[:, ::-1])


@pytest.mark.graph
@pytest.mark.gl
def test_light_switch_scales_emission_direct_and_ambient(ctx):
    scene = lit_room()
    second = ceiling_light([-1.5, -1.0, 2.49], 0.2, [10.0, 10, 12], ambient=[0.02, 0.03, 0.02])
    window = quad("window", [2.49, 0, 1.4], [0, 0, 0.4], [0, 0.5, 0], emission=np.array([3, 3, 4], "f4"))
    geo = SceneGeometry((*scene.surfaces, window), (*scene.lights, second))
    r = SceneRenderer(geo, ctx=ctx, shadow_size=128)
    eye = np.array([0.2, 0.1, 1.2])
    cube = {s: r.render_cubemap(eye, 32, np.array(s)) for s in [(0, 0), (1, 0), (0, 1), (1, 1), (0.5, 0)]}
    with pytest.raises(SceneError, match="light_scale"):
        r.render_cubemap(eye, 8, np.ones(3))
    r.release()
    window_px = sample_cubemap(cube[0, 0], np.array([1.0, 0, 0.1]))
    np.testing.assert_array_equal(window_px, [3, 3, 4])  # light_index -1: always on
    dark = cube[0, 0].copy()
    np.testing.assert_allclose(cube[1, 0] + cube[0, 1] - dark, cube[1, 1], rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(cube[0.5, 0] - dark, 0.5 * (cube[1, 0] - dark), rtol=1e-4, atol=1e-6)
    up = (scene.lights[0].center - eye) / np.linalg.norm(scene.lights[0].center - eye)
    np.testing.assert_array_equal(sample_cubemap(cube[1, 0], up), scene.lights[0].radiance.astype("f4"))
    np.testing.assert_array_equal(sample_cubemap(cube[0, 1], up), [0, 0, 0])
    floor_down = sample_cubemap(cube[0, 1], np.array([0, 0, -1.0]))
    assert np.all(floor_down > 0.8 * np.asarray(second.ambient))
    glowing = dark.any(-1)  # all lights off: only the window is left
    assert 0 < glowing.sum() < 0.1 * glowing.size and np.all(dark[glowing] == [3, 3, 4])


@pytest.mark.graph
@pytest.mark.gl
def test_texture_repeats_and_multiplies_color(ctx):
    tex = np.array([[[1.0, 0.5, 0.25], [0.2, 0.2, 0.2]]], np.float32)  # 2 x 1 texels, tiled every 1 m
    floor = quad("floor", [0, 0, 0], [4, 0, 0], [0, 4, 0], (0.5, 1.0, 1.0), uv_scale=1.0, texture=tex)
    light = ceiling_light([0, 0, 3.0], 0.1, [0, 0, 0], ambient=[1.0, 1.0, 1.0])
    r = SceneRenderer(SceneGeometry((floor,), (light,)), ctx=ctx, shadow_size=16)
    pose, K = look_down([0, 0, 1.0]), np.array([[40.0, 0, 100], [0, 40.0, 100], [0, 0, 1]])
    out, _ = r.render_pinhole(pose, K, 201, 201, np.ones(1))
    r.release()
    def at(x):  # the pixel seeing floor point (x, 0, 0)
        return out[100, round(100 + 40 * x)]
    for x in (0.25, 1.25, -0.75):
        np.testing.assert_allclose(at(x), [0.5, 0.5, 0.25], rtol=1e-3)
    for x in (0.75, 1.75, -1.25):
        np.testing.assert_allclose(at(x), [0.1, 0.2, 0.2], rtol=1e-3)
    np.testing.assert_allclose(at(1.0), [0.3, 0.35, 0.225], rtol=1e-3)  # GL_REPEAT blends across x = 1


@pytest.mark.gl
@pytest.mark.graph
def test_invalid_geometry_names_the_surface(ctx):
    bad = quad("floor", [0, 0, 0], [1, 0, 0], [0, 1, 0], light_index=2)
    with pytest.raises(SceneError, match="floor"):
        SceneRenderer(SceneGeometry((bad,), ()), ctx=ctx)


@pytest.mark.gl
@pytest.mark.graph
def test_own_context_is_created_and_released():
    floor = quad("floor", [0, 0, 0], [1, 0, 0], [0, 1, 0], emission=np.array([0.25, 0.5, 1.0], "f4"))
    r = SceneRenderer(SceneGeometry((floor,), ()))
    out, depth = r.render_pinhole(look_down([0, 0, 1.0]), np.array([[10.0, 0, 4], [0, 10.0, 4], [0, 0, 1]]), 9, 9,
                                  np.zeros(0))
    r.release()
    np.testing.assert_array_equal(out, np.broadcast_to([0.25, 0.5, 1.0], (9, 9, 3)))
    np.testing.assert_allclose(depth, 1.0, atol=1e-5)
