"""Turn a :class:`~probeless.scene.spec.Scene` into renderable :class:`SceneGeometry`.

Lights come first in ``SceneGeometry.lights`` (index = the scene's light index), windows after them.
Each light's ``ambient`` is the integrating-sphere estimate of the indirect radiance it adds to a
closed room: ``rho / (1 - rho) * radiance * area / S`` with ``rho`` the area-weighted mean albedo
and ``S`` the room's total surface area (flux ``pi L A``, indirect irradiance ``flux rho / (S (1 - rho))``).
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.color import from_srgb8
from probeless.errors import SceneError
from probeless.scene.geometry import AreaLight, SceneGeometry, Surface
from probeless.scene.obj import place_mesh, read_obj, vertex_normals
from probeless.scene.spec import Material, Scene
from probeless.scene.tessellate import box_faces, quad, triangulate

EMITTER_OFFSET_M = 0.002  # windows sit this far in front of their wall, to avoid z-fighting


def load_texture(path) -> np.ndarray:
    """Linear float32 RGB albedo texture (H, W, 3) from an sRGB image file."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise SceneError(f"{path}: cannot read texture image")
    return from_srgb8(img[:, :, ::-1])


def _surface(name: str, tris: tuple[np.ndarray, np.ndarray, np.ndarray], material: Material, **kw) -> Surface:
    pos, nrm, uv = tris
    texture = load_texture(material.texture) if material.texture is not None else None
    return Surface(name, pos.astype(np.float32), nrm.astype(np.float32), (uv / material.tile_m).astype(np.float32),
                   material.color.astype(np.float32), texture, **kw)


def build_geometry(scene: Scene) -> SceneGeometry:
    """All surfaces and area lights of ``scene`` (see the module docstring for the ordering)."""
    poly, h = scene.floorplan, scene.ceiling_height
    floor_tris = triangulate(poly)
    surfaces = [
        _surface("floor", _flat(poly, floor_tris, 0.0, up=True), scene.floor),
        _surface("ceiling", _flat(poly, floor_tris, h, up=False), scene.ceiling),
    ]
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        surfaces.append(_surface(f"wall{i}", _wall(a, b, 0.0, np.linalg.norm(b - a), 0.0, h), scene.walls))
    lights: list[AreaLight] = []
    for i, light in enumerate(scene.lights):
        c = light.position
        hu, hv = np.array([light.size[0] / 2, 0, 0]), np.array([0, light.size[1] / 2, 0])
        lights.append(AreaLight(f"light{i}", c, hu, hv, np.array([0.0, 0.0, -1.0]), light.radiance))
        surfaces.append(Surface(f"light{i}", *_panel(c, -hu, hv, np.array([0.0, 0.0, -1.0])),
                                np.zeros(3, np.float32), None, light.radiance.astype(np.float32), i))
    for j, win in enumerate(scene.windows):
        a, b = poly[win.wall], poly[(win.wall + 1) % n]
        d = (b - a) / np.linalg.norm(b - a)
        inward = np.array([-d[1], d[0], 0.0])
        c = np.array([*(a + d * win.center[0]), win.center[1]]) + inward * EMITTER_OFFSET_M
        hu, hv = np.array([*d, 0.0]) * win.size[0] / 2, np.array([0, 0, win.size[1] / 2])
        lights.append(AreaLight(f"window{j}", c, hu, hv, inward, win.radiance))
        surfaces.append(Surface(f"window{j}", *_panel(c, hu, hv, inward), np.zeros(3, np.float32), None,
                                win.radiance.astype(np.float32), len(lights) - 1))
    for k, item in enumerate(scene.furniture):
        plain = Material(item.color)
        if item.kind == "box":
            surfaces.append(_surface(f"furniture{k}", box_faces(item.center, item.size), plain))
        else:
            v, f = read_obj(item.path)
            world = place_mesh(v, item.up, item.scale, item.yaw_deg, item.position)
            normals = vertex_normals(world, f)
            surfaces.append(_surface(f"furniture{k}", (world[f].reshape(-1, 3), normals[f].reshape(-1, 3),
                                                       np.zeros((f.size, 2))), plain))
    return SceneGeometry(tuple(surfaces), tuple(_with_ambient(lights, surfaces)))


def _with_ambient(lights: list[AreaLight], surfaces: list[Surface]) -> list[AreaLight]:
    areas, albedo = [], []
    for s in surfaces:
        if s.emissive:
            continue
        p = s.positions.reshape(-1, 3, 3).astype(np.float64)
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
        mean = s.color * (s.texture.reshape(-1, 3).mean(axis=0) if s.texture is not None else 1.0)
        areas.append(area)
        albedo.append(mean)
    total = float(np.sum(areas))
    rho = np.clip(np.sum(np.array(albedo) * np.array(areas)[:, None], axis=0) / total, 0.0, 0.95)
    factor = rho / (1.0 - rho) / total
    return [AreaLight(li.name, li.center, li.half_u, li.half_v, li.normal, li.radiance,
                      ambient=factor * li.radiance * li.area) for li in lights]


def _flat(poly: np.ndarray, tris: np.ndarray, z: float, up: bool):
    order = tris if up else tris[:, ::-1]
    pos = np.concatenate([poly[order.reshape(-1)], np.full((order.size, 1), z)], axis=1)
    nrm = np.tile([0.0, 0.0, 1.0 if up else -1.0], (order.size, 1))
    return pos, nrm, pos[:, :2].copy()


def _wall(a: np.ndarray, b: np.ndarray, u0: float, u1: float, z0: float, z1: float):
    d = (b - a) / np.linalg.norm(b - a)
    inward = np.array([-d[1], d[0], 0.0])
    p0 = np.array([*(a + d * u0), z0])
    return quad(p0, np.array([*d, 0.0]) * (u1 - u0), np.array([0.0, 0.0, z1 - z0]), inward,
                uv0=(u0, z0), uv_size=(u1 - u0, z1 - z0))


def _panel(center, hu, hv, normal):
    pos, nrm, uv = quad(center - hu - hv, 2 * hu, 2 * hv, normal)
    return pos.astype(np.float32), nrm.astype(np.float32), uv.astype(np.float32)
