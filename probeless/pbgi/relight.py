"""Virtual objects relit by a room's point cloud, per camera frame: the work of the ``pbgi_renderer`` node and of
``probeless pbgi render`` (paper 001, §5).

:class:`Relighter` keeps one :class:`~probeless.pbgi.render.PbgiRenderer` and, for far fields, one
:class:`~probeless.hdr.splat.SplatRenderer` on the same GL context. Modes (:data:`MODES`):

* ``full`` -- PBGI gathers the whole cloud; empty micro-texels read an object's given envmap, else black;
* ``near_field`` -- PBGI gathers the points within ``near_radius`` of each object's centre; the rest comes from the
  far field: the given envmap, else the cubemap of the cloud's points beyond ``near_radius`` splatted at the centre;
* ``envmap`` -- no gathering: every direction reads the far field (the given envmap, else the whole cloud's cubemap
  at the object's centre) with the same shading -- the environment-map baseline.

A far field is per object, so with several objects the modes that use one render the view once per object and
keep each object's pixels (``full`` without envmaps renders once).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from probeless.errors import PbgiError, SceneError
from probeless.ibl.objects import object_from_dict, objects_problem
from probeless.pbgi.bsh import MAX_CLUSTER_RADIUS, BshReport, build_bsh
from probeless.pbgi.materials import brdf_from_material
from probeless.pbgi.modes import MODES
from probeless.pbgi.render import PbgiObject, PbgiRenderer

FAR_FACE = 64  # far-field cubemap face [texels]: the micro-buffers are 16-32 texels wide


@dataclass(frozen=True)
class Relit:
    """The objects seen from one camera, at the requested size; pixels (row, col)."""

    color: np.ndarray   # (H, W, 3) float32 linear radiance x exposure [camera linear units]
    mask: np.ndarray    # (H, W) bool, an object covers the pixel
    depth: np.ndarray   # (H, W) float32 camera z [m]; inf where mask is False
    stats: list         # MicroStats of each render that had an object in view


def pbgi_objects(specs) -> list[PbgiObject]:
    """The :class:`PbgiObject` of each ``objects`` mapping (the ``ibl_compositor`` format,
    :mod:`probeless.ibl.objects`). :class:`PbgiError` when a material has no PBGI BRDF (glass, mix)."""
    out = []
    for i, spec in enumerate(specs):
        obj = object_from_dict(spec, f"objects[{i}]")
        try:
            out.append(PbgiObject(obj.id, obj.mesh, brdf_from_material(obj.material)))
        except PbgiError as exc:
            raise PbgiError(f"objects[{i}].material: {exc}") from None
    return out


def pbgi_objects_problem(specs) -> str | None:
    """The ``objects`` param rule of ``pbgi_renderer``: that of ``ibl_compositor``, and every material has a BRDF."""
    problem = objects_problem(specs)
    if problem is None:
        try:
            pbgi_objects(specs)
        except (PbgiError, SceneError) as exc:
            return str(exc)
    return problem


def scaled_camera(K: np.ndarray, width: int, height: int, max_width: int) -> tuple[np.ndarray, int, int]:
    """(K, width, height) of the same pinhole camera at most ``max_width`` pixels wide (0: unchanged)."""
    if not max_width or width <= max_width:
        return np.asarray(K, np.float64), width, height
    s = max_width / width
    w, h = max_width, max(1, round(height * s))
    sx, sy = w / width, h / height
    K2 = np.asarray(K, np.float64).copy()
    K2[0, 0], K2[0, 2] = K2[0, 0] * sx, (K2[0, 2] + 0.5) * sx - 0.5   # pixel centres stay pixel centres
    K2[1, 1], K2[1, 2] = K2[1, 1] * sy, (K2[1, 2] + 0.5) * sy - 0.5
    return K2, w, h


def upscale(relit: Relit, width: int, height: int) -> Relit:
    """``relit`` resized to (width, height): mask and depth by nearest pixel, colour bilinearly over covered pixels
    only (normalised by the covered weight, so edges do not fade to black)."""
    h, w = relit.mask.shape
    if (w, h) == (width, height):
        return relit
    size = (width, height)
    mask = cv2.resize(relit.mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    depth = cv2.resize(np.where(relit.mask, relit.depth, 0).astype(np.float32), size, interpolation=cv2.INTER_NEAREST)
    weight = cv2.resize(relit.mask.astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    color = cv2.resize(relit.color * relit.mask[..., None], size, interpolation=cv2.INTER_LINEAR)
    color = np.where(mask[..., None], color / np.maximum(weight, 1e-6)[..., None], 0).astype(np.float32)
    return Relit(color, mask, np.where(mask, depth, np.inf).astype(np.float32), relit.stats)


class Relighter:
    """Objects relit by one cloud at a time (module docstring). ``renderer_kw`` go to
    :class:`~probeless.pbgi.render.PbgiRenderer` (variant, micro, exposure, near, far, ...)."""

    def __init__(self, objects: list[PbgiObject], *, mode: str = "full", near_radius: float = 1.0,
                 far_face: int = FAR_FACE, tc: float = 0.01, tn: float = 0.98, voxel: float | None = None,
                 max_radius: float = MAX_CLUSTER_RADIUS,
                 **renderer_kw):
        if mode not in MODES:
            raise PbgiError(f"unknown mode {mode!r} (known: {', '.join(MODES)})")
        self.mode, self.near_radius, self.far_face = mode, float(near_radius), int(far_face)
        self.bsh_kw = {"tc": tc, "tn": tn, "voxel": voxel, "max_radius": max_radius}
        self.renderer = PbgiRenderer(objects, **renderer_kw)
        self.objects = self.renderer.objects
        self.centres = [np.asarray(o.mesh.centre, np.float64) for o in self.objects]
        self.splat = None
        self.cloud: tuple | None = None       # (points float32, radiance float32, spacing or None)
        self.envmaps: dict[str, tuple[int, np.ndarray]] = {}  # object id -> (version, faces)
        self.far_cache: dict[int, np.ndarray] = {}
        self.version = 0
        self._far_key = None

    @property
    def ready(self) -> bool:
        """Whether a frame can be rendered: a cloud is set, or (envmap mode) every object has an envmap."""
        return self.cloud is not None or (self.mode == "envmap" and all(o.id in self.envmaps for o in self.objects))

    def set_cloud(self, points: np.ndarray, radiance: np.ndarray, normals: np.ndarray) -> BshReport | None:
        """Light by this cloud from now on ((N, 3) each: world [m], linear radiance, unit normals); builds the BSH
        (not in ``envmap`` mode) and returns its report."""
        report = None
        if self.mode != "envmap":
            bsh = build_bsh(points, radiance, normals, **self.bsh_kw)
            self.renderer.set_cloud(bsh)
            report = bsh.report
        self.cloud = (np.ascontiguousarray(points, np.float32), np.ascontiguousarray(radiance, np.float32), None)
        self.far_cache.clear()
        self.version += 1
        return report

    def set_envmap(self, object_id: str, faces: np.ndarray) -> None:
        """Use the cubemap ``faces`` (6, S, S, 3) linear [cloud units] as this object's far field."""
        if object_id not in {o.id for o in self.objects}:
            raise PbgiError(f"envmap for unknown object {object_id!r}")
        self.version += 1
        self.envmaps[object_id] = (self.version, np.asarray(faces, np.float32))

    def far_field(self, i: int) -> tuple[object, np.ndarray | None]:
        """(cache key, faces or None) of object ``i``'s far field in this mode."""
        oid = self.objects[i].id
        if oid in self.envmaps:
            version, faces = self.envmaps[oid]
            return ("envmap", oid, version), faces
        if self.mode == "full" or self.cloud is None:
            return None, None
        if i not in self.far_cache:
            self.far_cache[i] = self._cloud_cubemap(self.centres[i])
        return ("cloud", i, self.version), self.far_cache[i]

    def _cloud_cubemap(self, centre: np.ndarray) -> np.ndarray:
        from probeless.hdr.splat import SplatRenderer, cloud_cubemap, point_spacing

        points, radiance, spacing = self.cloud
        if spacing is None:
            spacing = point_spacing(points)
            self.cloud = (points, radiance, spacing)
        keep = slice(None)
        if self.mode == "near_field":
            keep = np.linalg.norm(points - centre.astype(np.float32), axis=1) > self.near_radius
            if not keep.any():
                return np.zeros((6, self.far_face, self.far_face, 3), np.float32)
        if self.splat is None:
            self.splat = SplatRenderer(self.renderer.ctx)
        faces, _ = cloud_cubemap(self.splat, points[keep], radiance[keep], spacing[keep], centre, self.far_face)
        return faces

    def _use_far(self, key, faces) -> None:
        if key != self._far_key:
            self.renderer.set_far_field(faces)
            self._far_key = key

    def render(self, K: np.ndarray, world_from_camera: np.ndarray, width: int, height: int,
               max_width: int = 0) -> Relit:
        """Every object seen through pinhole ``K`` from ``world_from_camera`` (4, 4, OpenCV axes), rendered at most
        ``max_width`` pixels wide (0: full size) and brought to (width, height)."""
        if not self.ready:
            raise PbgiError("render: no cloud yet" + (" and no envmap" if self.mode == "envmap" else ""))
        K2, w, h = scaled_camera(K, width, height, max_width)
        fars = [self.far_field(i) for i in range(len(self.objects))]
        variant = "envmap" if self.mode == "envmap" else None
        if all(f[1] is None for f in fars):  # full mode without envmaps: one render for every object
            self._use_far(None, None)
            r = self.renderer.render(K2, world_from_camera, w, h)
            return upscale(Relit(r.color, r.mask, r.depth, [r.stats] if r.stats else []), width, height)
        color, mask = np.zeros((h, w, 3), np.float32), np.zeros((h, w), bool)
        depth, stats = np.full((h, w), np.inf, np.float32), []
        for i, (key, faces) in enumerate(fars):
            self._use_far(key, faces)
            near = (self.centres[i], self.near_radius) if self.mode == "near_field" else None
            r = self.renderer.render(K2, world_from_camera, w, h, variant=variant, near=near)
            mine = r.gbuffer.object_index == i
            color[mine], mask[mine], depth[mine] = r.color[mine], True, r.depth[mine]
            if r.stats and mine.any():
                stats.append(r.stats)
        return upscale(Relit(color, mask, depth, stats), width, height)

    def release(self) -> None:
        """Free the GL objects and the context."""
        if self.splat is not None:
            self.splat.release()
            self.splat = None
        self.renderer.release()


def composite_relit(rgb8: np.ndarray, relit: Relit, real_depth: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 3) uint8: the camera frame ``rgb8`` with the relit objects drawn over it (no contact shadow: PBGI
    shades the objects only), hidden where ``real_depth`` [m] (0 = unknown) is nearer (:func:`~probeless.ibl.
    composite.composite`)."""
    from probeless.ibl.composite import composite
    from probeless.ibl.render import RenderResult

    shadow = np.ones(relit.color.shape, np.float32)
    return composite(rgb8, RenderResult(relit.color, relit.mask, relit.depth, shadow), real_depth)
