"""Ground truth for PBGI: Mitsuba 3 renders the object lit by the emitting reference room, one bounce.

Every patch of a :class:`~probeless.pbgi.room.ReferenceRoom` becomes a ``rectangle`` with an ``area``
emitter whose radiance is the patch's texture (``bitmap``, raw linear values, bilinear, clamped; the
convention of :mod:`probeless.pbgi.room`) and a black ``diffuse`` BSDF, so light reaches the camera
after at most one bounce on the object (``direct`` integrator: emitter and BSDF sampling with MIS).
The object is the room's sphere or a given :class:`~probeless.ibl.mesh_io.PlacedMesh`.

Materials (``material`` argument), radiance linear RGB, roughness perceptual (alpha = roughness^2):

- ``("lambert", base_rgb)``: ``diffuse``, f = base / pi.
- ``("ggx", f0_rgb, roughness)``: ``roughconductor``, distribution ``"ggx"``, material ``"none"`` (Fresnel
  1) times ``specular_reflectance = f0``; f = f0 D G / (4 cos_i cos_o) with Mitsuba's separable Smith
  G = G1(wi) G1(wo), visible-normal sampling. Roughness 0 becomes the smooth ``conductor`` (a mirror).
- ``("disney", base_rgb, roughness, metalness)``: Mitsuba's ``principled``. It differs from a textbook
  "metal/rough" model: its diffuse is Burley's (retro-reflection rising with roughness, not Lambert),
  the dielectric specular uses ``specular = 0.5`` (F0 = 0.04, Fresnel a blend of exact dielectric and
  Schlick), specular tint, sheen, clearcoat and transmission are 0, and there is no multiple scattering.
- Any object with attributes ``model`` (``"lambert"``, ``"ggx"`` or ``"disney"``), ``base_color``,
  ``roughness`` and ``metalness`` maps to the spec above; for ``"ggx"`` the base colour is f0. Texture
  maps (a true ``textured`` attribute) are refused.
"""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import numpy as np

from probeless.color import REC709_Y
from probeless.errors import PbgiError
from probeless.paths import REPO_ROOT
from probeless.pbgi.room import Patch, ReferenceRoom

VARIANT = "scalar_rgb"
OBJECT_ID = "object"


def _mitsuba():
    """The ``mitsuba`` module, variant set (imported lazily: it is heavy and optional)."""
    try:
        import mitsuba as mi
    except ImportError as exc:
        raise PbgiError("the Mitsuba reference needs mitsuba 3: pip install mitsuba") from exc
    if mi.variant() != VARIANT:
        mi.set_variant(VARIANT)
    return mi


def material_spec(material) -> tuple:
    """The tuple spec of ``material`` (a tuple, or a duck-typed Brdf; see module doc), validated."""
    if not isinstance(material, tuple):
        if getattr(material, "textured", False):
            raise PbgiError("the Mitsuba reference takes constant materials only, not texture maps")
        try:
            model = str(material.model).lower()
            base, rough, metal = material.base_color, material.roughness, material.metalness
        except AttributeError as exc:
            raise PbgiError(f"material {material!r}: expected a spec tuple or a Brdf-like object") from exc
        material = {"lambert": ("lambert", base), "ggx": ("ggx", base, rough),
                    "disney": ("disney", base, rough, metal)}.get(model, (model,))
    arity = {"lambert": 2, "ggx": 3, "disney": 4}
    if not material or material[0] not in arity or len(material) != arity[material[0]]:
        raise PbgiError(f"bad material {material!r}: expected ('lambert', rgb), ('ggx', f0_rgb, roughness) "
                        "or ('disney', rgb, roughness, metalness)")
    rgb = tuple(float(c) for c in np.broadcast_to(np.asarray(material[1], np.float64), (3,)))
    return (material[0], rgb, *(float(x) for x in material[2:]))


def bsdf_dict(material) -> dict:
    """Mitsuba BSDF dict of a material (module doc)."""
    spec = material_spec(material)
    rgb = {"type": "rgb", "value": list(spec[1])}
    if spec[0] == "lambert":
        return {"type": "diffuse", "reflectance": rgb}
    if spec[0] == "ggx":
        if spec[2] <= 0:
            return {"type": "conductor", "material": "none", "specular_reflectance": rgb}
        return {"type": "roughconductor", "distribution": "ggx", "alpha": spec[2] ** 2, "material": "none",
                "specular_reflectance": rgb}
    return {"type": "principled", "base_color": rgb, "roughness": spec[2], "metallic": spec[3]}


def _patch_shape(mi, patch: Patch) -> dict:
    """A patch as a rectangle (local x along edge_u, y along edge_v, z = normal) with a textured emitter."""
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = patch.edge_u / 2, patch.edge_v / 2, patch.normal
    m[:3, 3] = patch.origin + (patch.edge_u + patch.edge_v) / 2
    texture = {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(patch.radiance, np.float32)),
               "raw": True, "filter_type": "bilinear", "wrap_mode": "clamp"}
    luminance = float(np.mean(patch.radiance @ REC709_Y))
    return {"type": "rectangle", "to_world": mi.ScalarTransform4f(m.tolist()),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
            # emitters are picked in proportion to their power: the small bright lamp gets its share
            "emitter": {"type": "area", "radiance": texture,
                        "sampling_weight": max(patch.area * luminance, 1e-6)}}


def _object_shape(mi, room: ReferenceRoom, material, mesh):
    """The room's sphere, or ``mesh`` (a PlacedMesh) as a Mitsuba mesh with vertex normals."""
    bsdf = bsdf_dict(material)
    if mesh is None:
        return {"type": "sphere", "center": [float(c) for c in room.object_centre],
                "radius": float(room.object_radius), "bsdf": bsdf}
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    shape = mi.Mesh(OBJECT_ID, len(mesh.vertices), len(mesh.triangles), props=props, has_vertex_normals=True)
    params = mi.traverse(shape)
    params["vertex_positions"] = np.asarray(mesh.vertices, np.float32).ravel()
    params["faces"] = np.asarray(mesh.triangles, np.uint32).ravel()
    params["vertex_normals"] = np.asarray(mesh.normals, np.float32).ravel()
    params.update()
    return shape


def _sensor(mi, K: np.ndarray, world_from_camera: np.ndarray, width: int, height: int, spp: int) -> dict:
    """A Mitsuba ``perspective`` sensor equal to the OpenCV pinhole (K, world_from_camera), box filter."""
    K = np.asarray(K, np.float64)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if abs(fx - fy) > 1e-6 * fx or abs(K[0, 1]) > 1e-9:
        raise PbgiError(f"Mitsuba reference needs square pixels and no skew, got fx={fx} fy={fy} skew={K[0, 1]}")
    if abs(cx - (width - 1) / 2) > 1e-6 or abs(cy - (height - 1) / 2) > 1e-6:
        raise PbgiError(f"Mitsuba reference needs the principal point at the image centre "
                        f"({(width - 1) / 2}, {(height - 1) / 2}), got ({cx}, {cy})")
    # Mitsuba's camera frame is x left, y up, z forward; OpenCV's is x right, y down, z forward
    to_world = np.asarray(world_from_camera, np.float64) @ np.diag([-1.0, -1.0, 1.0, 1.0])
    return {"type": "perspective", "fov_axis": "x", "fov": float(np.degrees(2 * np.arctan(width / (2 * fx)))),
            "to_world": mi.ScalarTransform4f(to_world.tolist()), "near_clip": 1e-3, "far_clip": 1e3,
            "film": {"type": "hdrfilm", "width": int(width), "height": int(height), "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": int(spp)}}


def mitsuba_scene(room: ReferenceRoom, material, K: np.ndarray, world_from_camera: np.ndarray, width: int,
                  height: int, spp: int = 256, *, mesh=None) -> dict:
    """Mitsuba scene dict: the room's patches as emitters, the object (sphere or ``mesh``), the camera.

    ``K`` is an OpenCV pinhole (pixel centres at integer coordinates, principal point at the image
    centre), ``world_from_camera`` a 4x4 OpenCV camera pose (x right, y down, z forward) [m, world].
    """
    mi = _mitsuba()
    scene = {"type": "scene", "integrator": {"type": "direct"},
             "sensor": _sensor(mi, K, world_from_camera, width, height, spp),
             OBJECT_ID: _object_shape(mi, room, material, mesh)}
    for i, patch in enumerate(room.all_patches):
        scene[f"patch_{i:03d}_{patch.name}"] = _patch_shape(mi, patch)
    return scene


def pixel_rays(K: np.ndarray, world_from_camera: np.ndarray, u: np.ndarray, v: np.ndarray):
    """World ray origin (3,) and unit directions (..., 3) through image points (u, v) [px, OpenCV]."""
    K, T = np.asarray(K, np.float64), np.asarray(world_from_camera, np.float64)
    x = (u - K[0, 2] - K[0, 1] * (v - K[1, 2]) / K[1, 1]) / K[0, 0]
    d = np.stack([x, (v - K[1, 2]) / K[1, 1], np.ones_like(x)], axis=-1) @ T[:3, :3].T
    return T[:3, 3], d / np.linalg.norm(d, axis=-1, keepdims=True)


def object_mask(scene, K: np.ndarray, world_from_camera: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W) bool: pixels whose centre and four corners all see the object first (no edge pixels).

    ``scene`` is a loaded Mitsuba scene (``mi.load_dict(mitsuba_scene(...))``); rays are traced there,
    so occluders in front of the object count.
    """
    mi = _mitsuba()
    u, v = np.meshgrid(np.arange(width + 1) - 0.5, np.arange(height + 1) - 0.5)
    origin, dirs = pixel_rays(K, world_from_camera, u, v)
    corners = np.array([[_sees_object(mi, scene, origin, d) for d in row] for row in dirs])
    uc, vc = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    _, centre_dirs = pixel_rays(K, world_from_camera, uc, vc)
    centre = np.array([[_sees_object(mi, scene, origin, d) for d in row] for row in centre_dirs])
    return centre & corners[:-1, :-1] & corners[1:, :-1] & corners[:-1, 1:] & corners[1:, 1:]


def _sees_object(mi, scene, origin: np.ndarray, direction: np.ndarray) -> bool:
    si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*origin), mi.Vector3f(*direction)))
    return bool(si.is_valid()) and si.shape.id() == OBJECT_ID


def render_reference(room: ReferenceRoom, material, K: np.ndarray, world_from_camera: np.ndarray, width: int,
                     height: int, spp: int = 256, seed: int = 0, *, mesh=None, cache=None):
    """Render the object lit by ``room``: ``(image (H, W, 3) float32 linear radiance, mask (H, W) bool)``.

    ``mask`` marks pixels fully covered by the object (:func:`object_mask`). ``cache`` (a folder, or
    True for ``out/cache/mitsuba`` in the repository) stores results keyed by a hash of all inputs.
    """
    path = _cache_path(cache, room, material, K, world_from_camera, width, height, spp, seed, mesh)
    if path is not None and path.is_file():
        with np.load(path) as f:
            return f["image"], f["mask"]
    mi = _mitsuba()
    # serial, unmerged loading keeps the emitter order (and so each seed's image) the same run to run
    scene = mi.load_dict(mitsuba_scene(room, material, K, world_from_camera, width, height, spp, mesh=mesh),
                         parallel=False, optimize=False)
    image = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float32)[..., :3]
    mask = object_mask(scene, K, world_from_camera, width, height)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.stem}.{time.time_ns()}.tmp.npz")
        np.savez_compressed(tmp, image=image, mask=mask)
        tmp.replace(path)
    return image, mask


def _cache_path(cache, room, material, K, world_from_camera, width, height, spp, seed, mesh) -> Path | None:
    """``<cache>/<sha256 of every input>.npz``, or None without a cache."""
    if cache is None or cache is False:
        return None
    if cache is True:
        cache = REPO_ROOT / "out" / "cache" / "mitsuba"
    h = hashlib.sha256(repr((VARIANT, _version(), material_spec(material), width, height, spp, seed,
                             room.object_radius)).encode())
    arrays = [room.object_centre, np.asarray(K, np.float64), np.asarray(world_from_camera, np.float64)]
    for p in room.all_patches:
        arrays += [p.origin, p.edge_u, p.edge_v, p.radiance]
    if mesh is not None:
        arrays += [mesh.vertices, mesh.triangles, mesh.normals]
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(repr((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return Path(cache) / f"{h.hexdigest()[:32]}.npz"


def _version() -> str:
    return _mitsuba().__version__
