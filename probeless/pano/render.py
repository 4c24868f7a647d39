"""GPU image-based lighting of virtual objects by one equirectangular HDR frame (paper 002, §3 and §5).

:class:`PanoRenderer` keeps the frame as a mipmapped texture and the diffuse radiance map as a
bilinear one, and shades each object per fragment in world space: ``kd * D(N)`` (diffuse map),
``ks *`` the frame along the reflected ray (mirror) or the paper's glossy ring sampling about it
(:mod:`probeless.pano.glossy`: fixed ring pattern, a mip level per ring, trilinear filtering),
and ``kt *`` a Fresnel mix of refraction and reflection (glass). It also draws the background: the
perspective view of an LDR frame (what :func:`probeless.pano.view.view_equirect` computes).
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import ProbelessError
from probeless.geom.projection import clip_from_camera
from probeless.gl.context import create_context, current_context
from probeless.gl.programs import load_program, mat_bytes, set_uniforms
from probeless.gl.textures import upload_texture
from probeless.ibl.materials import shading
from probeless.pano import glossy
from probeless.pano.equirect import check_equirect
from probeless.pano.view import intrinsics

SHADERS = Path(__file__).with_name("shaders")


def _camera(K_or_fov, width: int, height: int) -> np.ndarray:
    """K itself, or the K of a horizontal field of view in degrees."""
    if np.isscalar(K_or_fov):
        return intrinsics(float(K_or_fov), width, height)
    return np.asarray(K_or_fov, np.float64)


def _upload(ctx: moderngl.Context, tex: moderngl.Texture | None, img: np.ndarray, mipmaps: bool) -> moderngl.Texture:
    """An equirect ``img`` in ``tex`` (rewritten when it matches): row 0 = image row 0 (v = row / H),
    repeating in u, clamped in v, bilinear, trilinear over a full mip chain with ``mipmaps``."""
    return upload_texture(ctx, img, tex, filter="trilinear" if mipmaps else "linear", repeat=(True, False))


def _write_array(prog, name: str, values: np.ndarray, size: int) -> None:
    """Fill uniform float array ``name`` (``size`` long) with ``values`` (zero padded), if the program uses it."""
    if name in prog:
        buf = np.zeros(size, np.float32)
        buf[: len(values)] = values
        prog[name].write(buf.tobytes())


class _Gpu:
    """Vertex buffers and shading constants of one object."""

    def __init__(self, ctx, prog, obj):
        m = obj.mesh
        self.obj, self.shade = obj, shading(obj.material)
        self.vbo = ctx.buffer(np.hstack([m.vertices, m.normals]).astype("f4").tobytes())
        self.ibo = ctx.buffer(m.triangles.astype("i4").tobytes())
        self.vao = ctx.vertex_array(prog, [(self.vbo, "3f 3f", "in_position", "in_normal")], index_buffer=self.ibo)
        self.ring: glossy.RingPattern | None = None  # for the current frame height
        self.ring_height = 0

    def release(self) -> None:
        for res in (self.vao, self.vbo, self.ibo):
            res.release()


class PanoRenderer:
    """Renders a fixed set of objects (:class:`probeless.ibl.render.IblObject`) lit by one HDR frame."""

    def __init__(self, objects, *, ctx: moderngl.Context | None = None, max_ring_samples: int = 64,
                 per_ring: int = 6, rings_inside: int = 3, rings_outside: int = 3, lod_bias: float = 0.0,
                 near: float = 0.02, far: float = 100.0):
        ids = [o.id for o in objects]
        if len(set(ids)) != len(ids):
            raise ProbelessError(f"PanoRenderer: object ids must be unique, got {ids}")
        if per_ring * (rings_inside + rings_outside) > max_ring_samples:
            raise ProbelessError(f"PanoRenderer: {per_ring} x ({rings_inside} + {rings_outside}) ring samples "
                                 f"exceed max_ring_samples={max_ring_samples}")
        self.own_ctx = ctx is None
        self.ctx = ctx or create_context()
        self.ctx.__enter__()
        self.prog = load_program(self.ctx, "pano_object", {"MAX_RING_SAMPLES": int(max_ring_samples)}, SHADERS)
        self.bg_prog = load_program(self.ctx, "pano_background", shader_dir=SHADERS)
        self.bg_vao = self.ctx.vertex_array(self.bg_prog, [])
        self.objects = {o.id: _Gpu(self.ctx, self.prog, o) for o in objects}
        self.ring_args = dict(per_ring=per_ring, rings_inside=rings_inside, rings_outside=rings_outside,
                              lod_bias=float(lod_bias))  # 0 = the paper's mip rule (glossy.ring_pattern)
        self.max_ring_samples, self.near, self.far = max_ring_samples, near, far
        self.env = self.diffuse = self.frame = None
        self._targets: dict = {}

    @current_context
    def set_environment(self, hdr: np.ndarray, diffuse: np.ndarray) -> None:
        """Light every object by the equirect ``hdr`` (H, 2H, 3) and its diffuse map (h, 2h, 3) from now on."""
        check_equirect(hdr, "set_environment: hdr")
        check_equirect(diffuse, "set_environment: diffuse")
        self.env = _upload(self.ctx, self.env, hdr, mipmaps=True)
        self.diffuse = _upload(self.ctx, self.diffuse, diffuse, mipmaps=False)
        height = hdr.shape[0]
        for g in self.objects.values():
            if g.shade.roughness > 0 and g.shade.ks.any() and g.ring_height != height:
                g.ring = glossy.ring_pattern(g.shade.roughness, height, **self.ring_args)
                g.ring_height = height

    @current_context
    def set_background(self, frame: np.ndarray) -> None:
        """Use the equirect ``frame`` (uint8 display values, or floats in 0..1) as the background from now on."""
        check_equirect(frame, "set_background")
        self.frame = _upload(self.ctx, self.frame, frame, mipmaps=False)

    def _target(self, kind: str, width: int, height: int):
        key = (kind, width, height)
        if key not in self._targets:
            color = self.ctx.texture((width, height), 4, dtype="f4" if kind == "objects" else "f1")
            depth = self.ctx.depth_renderbuffer((width, height)) if kind == "objects" else None
            self._targets[key] = (self.ctx.framebuffer([color], depth), color, depth)
        return self._targets[key]

    @current_context
    def render(self, K_or_fov, world_from_camera: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """(color (H, W, 3) float32 linear radiance, mask (H, W) bool) of every object seen from the pose."""
        if self.env is None:
            raise ProbelessError("PanoRenderer.render: no environment yet (call set_environment first)")
        K = _camera(K_or_fov, width, height)
        fbo, color, _ = self._target("objects", width, height)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        clip = clip_from_camera(K, width, height, self.near, self.far) @ np.linalg.inv(world_from_camera)
        p = self.prog
        p["clip_from_world"].write(mat_bytes(clip))
        self.env.use(0)
        self.diffuse.use(1)
        for g in self.objects.values():
            s = g.shade
            set_uniforms(p, env=0, diffuse_map=1, camera_position=tuple(np.asarray(world_from_camera)[:3, 3]),
                         kd=tuple(s.kd), ks=tuple(s.ks), kt=tuple(s.kt), ior=float(s.ior),
                         n_samples=0 if g.ring is None else len(g.ring.weights))
            if g.ring is not None:
                for name in ("angles", "azimuths", "weights", "lods"):
                    _write_array(p, "ring_" + name[:-1], getattr(g.ring, name), self.max_ring_samples)
            g.vao.render(moderngl.TRIANGLES)
        rgba = np.frombuffer(color.read(), np.float32).reshape(height, width, 4)
        return rgba[..., :3].copy(), rgba[..., 3] > 0.5

    @current_context
    def background(self, K_or_fov, world_from_camera: np.ndarray, width: int, height: int) -> np.ndarray:
        """(H, W, 3) uint8 perspective view of the background frame (translation ignored)."""
        if self.frame is None:
            raise ProbelessError("PanoRenderer.background: no frame yet (call set_background first)")
        K = _camera(K_or_fov, width, height)
        fbo, color, _ = self._target("background", width, height)
        fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.frame.use(0)
        world_from_pixel = np.asarray(world_from_camera, np.float64)[:3, :3] @ np.linalg.inv(K)
        self.bg_prog["frame"] = 0
        self.bg_prog["world_from_pixel"].write(mat_bytes(world_from_pixel))
        self.bg_vao.render(moderngl.TRIANGLES, vertices=3)
        return np.frombuffer(fbo.read(components=3, alignment=1), np.uint8).reshape(height, width, 3).copy()

    def _release(self, names) -> None:
        for name in names:
            tex = getattr(self, name)
            if tex is not None:
                tex.release()
            setattr(self, name, None)

    @current_context
    def release(self) -> None:
        """Free every GL resource (the context too when this renderer created it)."""
        self._release(("env", "diffuse", "frame"))
        for g in self.objects.values():
            g.release()
        for fbo, color, depth in self._targets.values():
            for res in (fbo, color, depth):
                if res is not None:
                    res.release()
        self._targets = {}
        self.bg_vao.release()
        if self.own_ctx:
            self.ctx.release()
