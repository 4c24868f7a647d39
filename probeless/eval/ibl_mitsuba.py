"""The compute part of ``probeless eval ibl``: spheres drawn by the ``ibl_compositor``'s own path vs Mitsuba 3.

Ours: the map becomes a ``lighting/Cubemap`` message (linear, float16, as the cubemap node publishes an HDR map)
and its ``lighting/SHCoefficients`` (5 bands, :func:`probeless.envmap.sh.project_cubemap` as the node computes them),
then :func:`probeless.ibl.lighting.lighting_from_messages` and :class:`probeless.ibl.render.IblRenderer`: the
functions the node calls. Mitsuba: the same sphere (analytic), an ``envmap`` emitter, ``direct`` integrator (one
bounce; a sphere sees no other part of itself), glass through ``path`` (it needs the way through the sphere).

The Mitsuba envmap bitmap is not copied from the panorama: every pixel of it gets its world direction from
Mitsuba's documented ``envmap`` convention (:func:`mitsuba_envmap_directions`) and its radiance from the project's
own direction -> map lookup (:func:`probeless.pano.mips.sample_equirect` for a panorama, the cube lookup for a
cubemap), so the comparison holds whatever the project's panorama orientation is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.color import REC709_Y
from probeless.geom.cube import cube_directions, sample_cubemap

CENTRE = np.zeros(3)     # sphere centre [m, world]
RADIUS = 1.0             # sphere radius [m]
EYE = np.array([3.6, -1.2, 1.0])  # camera position [m, world]
MITSUBA_MAP = (512, 1024)  # Mitsuba envmap bitmap (rows, cols) [px]


@dataclass(frozen=True)
class Case:
    """One material row: ours (a compositor material) and Mitsuba's BSDF dict for the same surface."""

    name: str
    material: object        # probeless.ibl.materials material
    bsdf: dict | tuple      # Mitsuba BSDF dict, or several whose renders add up (a layered material)
    goal: bool              # row of the <= 5 % goal (diffuse, mirror, GGX)
    compensated: bool = False  # also render ours with the energy compensation (what ships) for the mean ratio


def cases(roughnesses) -> list[Case]:
    """The materials the compositor draws, each with its Mitsuba twin (roughness: alpha = roughness²)."""
    from probeless.ibl.materials import Diffuse, Glass, Metal, Mirror, Principled

    white = {"type": "rgb", "value": [1.0, 1.0, 1.0]}
    out = [Case("diffuse", Diffuse((0.8, 0.8, 0.8)), {"type": "diffuse", "reflectance": {"type": "rgb",
                                                                                         "value": [0.8] * 3}}, True),
           Case("mirror", Mirror(), {"type": "conductor", "material": "none", "specular_reflectance": white}, True)]
    for r in roughnesses:
        out.append(Case(f"ggx {r:g}", Metal((1.0, 1.0, 1.0), float(r)),
                        {"type": "roughconductor", "distribution": "ggx", "alpha": float(r) ** 2, "material": "none",
                         "specular_reflectance": white}, True, compensated=True))
    base, rough = [0.7, 0.35, 0.2], 0.4
    # diffuse + a GGX lobe with the Fresnel of a dielectric of ior 1.5 (f0 = 0.04): two renders, added
    out.append(Case("principled", Principled(tuple(base), rough, 0.0),
                    ({"type": "diffuse", "reflectance": {"type": "rgb", "value": base}},
                     {"type": "roughconductor", "distribution": "ggx", "alpha": rough ** 2, "eta": 1.5, "k": 0.0}),
                    False, compensated=True))
    out.append(Case("glass", Glass(1.5), {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0}, False))
    return out


def camera(size: int) -> tuple[np.ndarray, np.ndarray]:
    """(K, world_from_camera) of the OpenCV camera looking at the sphere, which fills about 80 % of the width."""
    from probeless.scene.trajectory import look_at

    dist = float(np.linalg.norm(EYE - CENTRE))
    f = 0.5 * size / np.tan(np.arcsin(RADIUS / dist) / 0.8)
    K = np.array([[f, 0, (size - 1) / 2], [0, f, (size - 1) / 2], [0, 0, 1.0]])
    return K, look_at(EYE, CENTRE)


def sphere_mask(K: np.ndarray, pose: np.ndarray, size: int) -> np.ndarray:
    """(H, W) bool: pixels whose centre and four corners all hit the analytic sphere (no edge pixels)."""
    from probeless.pbgi.reference import pixel_rays

    def hits(u, v):
        o, d = pixel_rays(K, pose, u, v)
        oc = o - CENTRE
        b = d @ oc
        return b * b - (oc @ oc - RADIUS ** 2) > 0

    uc, vc = np.meshgrid(np.arange(size + 1) - 0.5, np.arange(size + 1) - 0.5)
    corner = hits(uc, vc)
    u, v = np.meshgrid(np.arange(size, dtype=float), np.arange(size, dtype=float))
    return hits(u, v) & corner[:-1, :-1] & corner[1:, :-1] & corner[:-1, 1:] & corner[1:, 1:]


def mitsuba_envmap_directions(rows: int, cols: int) -> np.ndarray:
    """(rows, cols, 3) world direction of every pixel centre of a Mitsuba 3 ``envmap`` bitmap, identity ``to_world``.

    Mitsuba 3 (``src/emitters/envmap.cpp``, ``eval``): a direction ``v`` reads the bitmap at
    ``u = atan2(v.x, -v.z) / 2 pi`` (wrapped), ``s = acos(v.y) / pi``, bilinear, with column centres at
    ``u = (c + 0.5) / cols`` but row centres at ``s = r / (rows - 1)`` (first and last rows on the poles; measured
    through ``Emitter.eval`` in tests/ibl/test_eval_ibl.py). So pixel (r, c) looks along
    ``(sin t sin p, cos t, -sin t cos p)`` with ``p = 2 pi (c + 0.5) / cols``, ``t = pi r / (rows - 1)``.
    """
    t = np.pi * np.arange(rows) / (rows - 1)
    p = 2 * np.pi * (np.arange(cols) + 0.5) / cols
    t, p = np.meshgrid(t, p, indexing="ij")
    return np.stack([np.sin(t) * np.sin(p), np.cos(t), -np.sin(t) * np.cos(p)], axis=-1)


def panorama_lookup(equirect: np.ndarray):
    """direction (..., 3) -> radiance (..., 3) of an equirectangular panorama (the project's convention, bilinear)."""
    from probeless.pano.mips import sample_equirect

    img = np.ascontiguousarray(equirect[..., :3], np.float32)
    return lambda d: sample_equirect([img], d)


def cube_lookup(faces: np.ndarray):
    """direction (..., 3) -> radiance (..., 3) of a cubemap (nearest texel, the project's cube convention)."""
    return lambda d: sample_cubemap(faces, d)


def cube_from_lookup(lookup, size: int, supersample: int = 2) -> np.ndarray:
    """(6, S, S, 3) float32 cubemap of a direction -> radiance function, ``supersample``² lookups per texel."""
    big = cube_directions(size * supersample)
    f = lookup(big / np.linalg.norm(big, axis=-1, keepdims=True)).astype(np.float64)
    return f.reshape(6, size, supersample, size, supersample, 3).mean(axis=(2, 4)).astype(np.float32)


def render_ours(faces: np.ndarray, case: Case, K, pose, size: int, ctx, compensated: bool, **renderer) -> np.ndarray:
    """(H, W, 3) the sphere as the ``ibl_compositor`` draws it: Cubemap + SH messages -> lighting -> renderer."""
    from probeless.envmap.sh import project_cubemap
    from probeless.ibl.lighting import lighting_from_messages
    from probeless.ibl.mesh_io import place, uv_sphere
    from probeless.ibl.render import IblObject, IblRenderer
    from probeless.messages.header import Header
    from probeless.messages.lighting import Cubemap, SHCoefficients

    header = Header(0, "world")
    cube = Cubemap(header, "sphere", CENTRE.copy(), np.clip(faces, 0, 65504).astype(np.float16), (), linear=True)
    sh = SHCoefficients(header, "sphere", 5, project_cubemap(faces, 5).astype(np.float32))
    mesh = place(*uv_sphere(), CENTRE, radius=RADIUS)
    r = IblRenderer([IblObject("sphere", mesh, case.material, contact_shadow=False)], ctx=ctx,
                    energy_compensation=compensated, **renderer)
    try:
        r.set_lighting("sphere", lighting_from_messages(cube, sh))
        return r.render(K, pose, size, size).color.astype(np.float64)
    finally:
        r.release()


_BITMAPS: dict[int, tuple] = {}


def mitsuba_bitmap(lookup) -> np.ndarray:
    """(rows, cols, 3) float32 Mitsuba envmap bitmap of a direction -> radiance lookup (module doc), cached."""
    if id(lookup) not in _BITMAPS:
        _BITMAPS.clear()
        _BITMAPS[id(lookup)] = (lookup, lookup(mitsuba_envmap_directions(*MITSUBA_MAP)).astype(np.float32))
    return _BITMAPS[id(lookup)][1]


def render_mitsuba(lookup, case: Case, K, pose, size: int, spp: int, seed: int) -> np.ndarray:
    """(H, W, 3) Mitsuba 3's render of the sphere under the envmap filled through ``lookup`` (module doc)."""
    from probeless.pbgi.reference import _mitsuba, _sensor

    mi = _mitsuba()
    bitmap = mi.Bitmap(mitsuba_bitmap(lookup))
    out = np.zeros((size, size, 3))
    for bsdf in (case.bsdf,) if isinstance(case.bsdf, dict) else case.bsdf:
        integrator = {"type": "path", "max_depth": 16} if bsdf["type"] == "dielectric" else {"type": "direct"}
        scene = mi.load_dict({"type": "scene", "integrator": integrator,
                              "sensor": _sensor(mi, K, pose, size, size, spp),
                              "env": {"type": "envmap", "bitmap": bitmap},
                              "sphere": {"type": "sphere", "center": CENTRE.tolist(), "radius": RADIUS,
                                         "bsdf": bsdf}})
        out += np.array(mi.render(scene, spp=spp, seed=seed), np.float64)[..., :3]
    return out


def compare(ours: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """rel_rms = ||Y_ours - Y_ref|| / ||Y_ref|| and mean_ratio = mean Y_ours / mean Y_ref over ``mask`` (Rec. 709 Y)."""
    y, yr = ours[mask] @ REC709_Y, ref[mask] @ REC709_Y
    return {"rel_rms": float(np.linalg.norm(y - yr) / np.linalg.norm(yr)), "mean_ratio": float(y.mean() / yr.mean())}


def reference_noise(ref_a: np.ndarray, ref_b: np.ndarray, mask: np.ndarray) -> float:
    """Relative RMS noise of the mean of two independent references: ||Y_a - Y_b|| / (2 ||(Y_a + Y_b) / 2||)."""
    ya, yb = ref_a[mask] @ REC709_Y, ref_b[mask] @ REC709_Y
    return float(np.linalg.norm(ya - yb) / np.linalg.norm(ya + yb))
