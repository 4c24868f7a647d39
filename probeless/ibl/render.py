"""GPU image-based lighting of virtual objects seen by a pinhole camera (paper §4.8).

:class:`IblRenderer` draws each object with its material under its own environment (a samplerCube with its full
mip chain, sampled with world directions) into linear colour in camera units, a mask and a depth image, and
the contact shadow of each object on its supporting plane as a per-pixel ratio
(occluded / unoccluded irradiance, by differential PRT: transfer vectors of a floor grid computed at
load time by ray casting against the object, dotted with the object's SH each frame).

Specular (``probeless/gl/glsl/ibl_specular.glsl``; GGX, alpha = roughness², Schlick Fresnel, separable Smith masking,
Filament's multiple-scattering compensation unless ``energy_compensation=False``). The ``lobe`` argument:

* ``hybrid`` (default): the lobe is importance-sampled (visible normals, filtered trilinear lookups) over the
  pixel's whole footprint: a grid of sub-pixel cells, each on the exact surface under it (the osculating quadric of
  the pixel centre, hit by the cell's camera ray), with as many lookups as the footprint and the lobe cover level-0
  texels (16 each, at least ``spec_samples`` / ``aa_samples``, at most 2048); lobes rougher than 0.18 (for 256-px
  faces) sample the map minus its brightest texels (:func:`probeless.ibl.prefilter.extract_light_parts`) and add
  those texels as lights with the exact BRDF, averaged over a grid of sub-pixel frames as fine as the lobe needs,
  each light near the reflection of a narrow lobe as its 16 parts, so a small, very bright light weighs exactly
  its share in every pixel;
* ``split_sum``: the GGX-prefiltered chain (:mod:`probeless.ibl.prefilter`, trilinear between levels) times the DFG
  term (:mod:`probeless.ibl.dfg`), the classic split sum (cheap, 10-20 % RMS off a path tracer at mid roughness);
  ``sampled``: importance sampling of the whole map; ``texel_sum``: exact sums over a 16-32 px level (a slow
  reference).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import moderngl
import numpy as np

from probeless.envmap.sh import cosine_lobe
from probeless.errors import ProbelessError
from probeless.geom.projection import clip_from_camera
from probeless.gl.context import GL_TEXTURE_CUBE_MAP_SEAMLESS, create_context, current_context
from probeless.gl.programs import load_program, mat_bytes, set_uniforms
from probeless.gl.textures import upload_cube, upload_texture
from probeless.ibl import prt
from probeless.ibl.dfg import dfg_table
from probeless.ibl.lighting import Lighting, glossy_faces
from probeless.ibl.materials import shading
from probeless.ibl.mesh_io import PlacedMesh
from probeless.ibl.prefilter import LIGHT_FACE, GgxPrefilter, chain_levels, extract_light_parts, level_roughness

SHADERS = Path(__file__).with_name("shaders")
LOBES = ("hybrid", "split_sum", "texel_sum", "sampled")
SUM_ROUGHNESS = 0.3  # "texel_sum": lobes at least this rough are summed over the texels of a small mip level
SUM_FACE = ((0.55, 16), (SUM_ROUGHNESS, 32))  # (roughness from, face size of the summed level [texels])
MAX_LIGHTS = 128   # object.frag.glsl's MAX_LIGHTS (>= probeless.ibl.prefilter.LIGHTS)
SPEC_SAMPLES = 128  # lookups per pixel of a rough specular lobe at least (importance-sampled, filtered) [count]
AA_SAMPLES = 64    # lookups per pixel of a mirror (roughness 0) or a refraction at least, over the pixel [count]


def sum_level(roughness: float, size: int) -> int:
    """The mip level of an S = ``size`` map whose texels the "exact" lobe sums for ``roughness`` (-1: none, the lobe
    is importance-sampled: smoother than SUM_ROUGHNESS)."""
    for rough, face in SUM_FACE:
        if roughness >= rough:
            return max(0, int(np.log2(max(1, size) / face)))
    return -1


@dataclass(frozen=True)
class IblObject:
    """A virtual object: placed mesh, material and contact-shadow settings."""

    id: str
    mesh: PlacedMesh
    material: Any
    contact_shadow: bool = True
    floor_z: float | None = None   # supporting plane height; None = the mesh's lowest point [m, world]
    shadow_extent: float = 4.0     # half side of the shadow grid [bounding radii]
    prt_dirs: int = 512            # rays per vertex for the PRT precomputation [count]


@dataclass(frozen=True)
class RenderResult:
    """One rendered view; pixels (row, col) of the camera image."""

    color: np.ndarray    # (H, W, 3) float32 linear radiance x exposure [camera linear units]
    mask: np.ndarray     # (H, W) bool, a virtual object covers the pixel
    depth: np.ndarray    # (H, W) float32 camera z of the object [m]; inf where mask is False
    shadow: np.ndarray   # (H, W, 3) float32 factor for the real image (1 = unchanged; contact shadows < 1)
    missing: tuple[str, ...] = ()  # objects not drawn because they have no lighting yet


class _Gpu:
    """GPU buffers and precomputed transfer of one object."""

    def __init__(self, ctx, obj_prog, floor_prog, obj: IblObject):
        m, self.obj = obj.mesh, obj
        self.shade = shading(obj.material)
        n = len(m.vertices)
        self.prt = prt.transfer_vectors(m, m.vertices, m.normals, n_dirs=obj.prt_dirs) if self.shade.shadowed else None
        self.vbo = ctx.buffer(np.hstack([m.vertices, m.normals]).astype("f4").tobytes())
        self.prt_vbo = ctx.buffer(np.zeros((n, 3), "f4").tobytes())
        self.ibo = ctx.buffer(m.triangles.astype("i4").tobytes())
        self.vao = ctx.vertex_array(obj_prog, [(self.vbo, "3f 3f", "in_position", "in_normal"),
                                               (self.prt_vbo, "3f", "in_prt")], index_buffer=self.ibo)
        self.floor_vao = None
        if obj.contact_shadow:
            centre, half = m.centre[:2], obj.shadow_extent * m.radius
            z = m.vertices[:, 2].min() if obj.floor_z is None else obj.floor_z
            verts, tris = prt.floor_grid(centre, half, z)
            up = np.tile([0.0, 0.0, 1.0], (len(verts), 1))
            self.floor_t = prt.transfer_vectors(m, verts, up, n_dirs=obj.prt_dirs, offset=1e-4 * m.radius)
            self.floor_t0 = prt.unshadowed_transfer(up[:1], n_dirs=obj.prt_dirs)[0]
            self.falloff = prt.edge_falloff(verts, centre, half)
            self.floor_pos = ctx.buffer(verts.astype("f4").tobytes())
            self.floor_ratio = ctx.buffer(np.ones((len(verts), 3), "f4").tobytes())
            self.floor_ibo = ctx.buffer(tris.astype("i4").tobytes())
            self.floor_vao = ctx.vertex_array(floor_prog, [(self.floor_pos, "3f", "in_position"),
                                                           (self.floor_ratio, "3f", "in_ratio")],
                                              index_buffer=self.floor_ibo)
        self.env = self.glossy = self.chain = self.residual = self.parts = None
        self.sum_level = -1
        self.lights = (np.zeros((0, 3), "f4"), np.zeros((0, 3), "f4"))  # (directions, powers) of the lobe's lights

    def set_lighting(self, ctx, lighting: Lighting, prefilter=None, lobe: str = "hybrid") -> None:
        """Upload the environment (with its full mip chain) and evaluate the per-vertex PRT radiance and floor
        shadow ratio. Explicit prefiltered ``lighting.levels`` are uploaded for the lobe (read as they are)."""
        self.release_textures()
        self.env = upload_cube(ctx, np.asarray(lighting.faces, np.float32))
        self.env_size = float(lighting.faces.shape[1])
        pre = glossy_faces(lighting, self.shade.roughness)
        spec = pre is None and (self.shade.ks.any() or self.shade.f90.any())
        rough = spec and self.shade.roughness >= level_roughness(chain_levels(lighting.faces.shape[1]))[1]
        self.lights = (np.zeros((0, 3), "f4"), np.zeros((0, 3), "f4"))
        if rough and lobe == "hybrid":
            residual, dirs, powers, part_dirs, part_powers = extract_light_parts(lighting.faces)
            self.lights = (dirs, powers)
            self.residual = upload_cube(ctx, residual)
            if len(dirs):
                parts = np.concatenate([part_dirs, part_powers])  # row k: light k's part directions, n + k: powers
                self.parts = upload_texture(ctx, np.ascontiguousarray(parts, np.float32), filter="nearest")
        self.chain, levels = prefilter.chain(lighting.faces) if rough and lobe == "split_sum" else (None, 1)
        self.chain_max_level = float(levels - 1)
        self.sum_level = sum_level(self.shade.roughness, lighting.faces.shape[1]) if lobe == "texel_sum" else -1
        self.chain_max_level = float(levels - 1)
        self.glossy = upload_cube(ctx, np.asarray(pre, np.float32)) if pre is not None else None
        sh = lighting.sh[:25]
        per_row = np.repeat(cosine_lobe(5), [2 * b + 1 for b in range(5)])
        self.sh_irr = (sh * per_row[:, None]).astype("f4")
        if self.prt is not None:
            self.prt_vbo.write((self.prt @ sh).astype("f4").tobytes())
        if self.floor_vao is not None:
            lit, free = self.floor_t @ sh, self.floor_t0 @ sh
            ratio = np.where(free > 1e-8, lit / np.maximum(free, 1e-8), 1.0).clip(0.0, 1.0)
            ratio = 1.0 - (1.0 - ratio) * self.falloff[:, None]
            self.floor_ratio.write(ratio.astype("f4").tobytes())

    def release_textures(self) -> None:
        for tex in (self.env, self.glossy, self.chain, self.residual, self.parts):
            if tex is not None:
                tex.release()
        self.env = self.glossy = self.chain = self.residual = self.parts = None

    def release(self) -> None:
        self.release_textures()
        for res in (self.vao, self.vbo, self.prt_vbo, self.ibo, self.floor_vao):
            if res is not None:
                res.release()
        if self.floor_vao is not None:
            for res in (self.floor_pos, self.floor_ratio, self.floor_ibo):
                res.release()


class IblRenderer:
    """Renders a fixed set of :class:`IblObject` lit by per-object :class:`Lighting`."""

    def __init__(self, objects: list[IblObject], *, exposure: float = 1.0, near: float = 0.05, far: float = 50.0,
                 ctx: moderngl.Context | None = None, spec_samples: int = SPEC_SAMPLES, aa_samples: int = AA_SAMPLES,
                 energy_compensation: bool = True, lobe: str = "hybrid"):
        self.own_ctx = ctx is None
        self.ctx = ctx or create_context()
        self.ctx.__enter__()
        self.ctx.enable_direct(GL_TEXTURE_CUBE_MAP_SEAMLESS)
        self.obj_prog = load_program(self.ctx, "object", shader_dir=SHADERS)
        self.dfg = upload_texture(self.ctx, dfg_table(), filter="linear")
        self.spec_samples, self.aa_samples = int(spec_samples), int(aa_samples)
        self.energy_compensation = bool(energy_compensation)
        if lobe not in LOBES:
            raise ProbelessError(f"IblRenderer: lobe must be one of {', '.join(LOBES)}, got {lobe!r}")
        self.lobe = lobe
        self.prefilter = GgxPrefilter(self.ctx)
        self.floor_prog = load_program(self.ctx, "floor", shader_dir=SHADERS)
        self.objects = {o.id: _Gpu(self.ctx, self.obj_prog, self.floor_prog, o) for o in objects}
        self.exposure, self.near, self.far = exposure, near, far
        self._targets = None

    @current_context
    def set_lighting(self, object_id: str, lighting: Lighting) -> None:
        """Light object ``object_id`` by ``lighting`` from now on."""
        g = self.objects[object_id]
        g.set_lighting(self.ctx, lighting, self.prefilter, self.lobe)

    def _framebuffers(self, width: int, height: int):
        if self._targets is None or self._targets[0] != (width, height):
            if self._targets is not None:
                for res in self._targets[1:]:
                    res.release()
            color = self.ctx.texture((width, height), 4, dtype="f4")
            zbuf = self.ctx.texture((width, height), 1, dtype="f4")
            shadow = self.ctx.texture((width, height), 4, dtype="f4")
            depth = self.ctx.depth_renderbuffer((width, height))
            self._targets = ((width, height), self.ctx.framebuffer([color, zbuf], depth),
                             self.ctx.framebuffer([shadow], depth), color, zbuf, shadow, depth)
        return self._targets[1:]

    @current_context
    def render(self, K: np.ndarray, world_from_camera: np.ndarray, width: int, height: int) -> RenderResult:
        """Draw every lit object seen from ``world_from_camera`` through pinhole ``K`` at ``width`` x ``height``."""
        fbo, shadow_fbo, color, zbuf, shadow, _ = self._framebuffers(width, height)
        camera_from_world = np.linalg.inv(world_from_camera)
        clip = mat_bytes(clip_from_camera(K, width, height, self.near, self.far) @ camera_from_world)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        p = self.obj_prog
        p["clip_from_world"].write(clip)
        p["camera_from_world"].write(mat_bytes(camera_from_world))
        drawn = [g for g in self.objects.values() if g.env is not None]
        self.dfg.use(2)
        for g in drawn:
            s = g.shade
            (g.glossy or g.env).use(1)
            g.env.use(0)
            (g.chain or g.env).use(3)
            (g.residual or g.env).use(4)
            (g.parts or self.dfg).use(5)
            set_uniforms(p, env=0, glossy=1, dfg=2, chain=3, residual=4, chain_max_level=g.chain_max_level,
                         split_sum=g.chain is not None, sum_level=int(g.sum_level), use_levels=g.glossy is not None,
                         env_size=g.env_size,
                         camera_position=tuple(world_from_camera[:3, 3]),
                         kd=tuple(s.kd), ks=tuple(s.ks), f90=tuple(s.f90), roughness=float(s.roughness),
                         kt=tuple(s.kt), ior=float(s.ior), energy_compensation=self.energy_compensation,
                         spec_samples=self.aa_samples if s.roughness <= 0 or g.chain is not None else self.spec_samples,
                         refr_samples=self.aa_samples, use_prt=g.prt is not None, exposure=float(self.exposure))
            if "sh_irr" in p:
                p["sh_irr"].write(g.sh_irr.tobytes())
            n_lights = len(g.lights[0])
            set_uniforms(p, light_count=n_lights, light_parts=5, light_split=g.parts.width if g.parts else 0,
                         light_size=float(np.pi / (2 * LIGHT_FACE)))
            if n_lights and "light_dir" in p:
                p["light_dir"].write(np.pad(g.lights[0], ((0, MAX_LIGHTS - n_lights), (0, 0))).astype("f4").tobytes())
                p["light_power"].write(np.pad(g.lights[1], ((0, MAX_LIGHTS - n_lights), (0, 0))).astype("f4").tobytes())
            g.vao.render(moderngl.TRIANGLES)
        shadow_fbo.use()
        shadow_fbo.clear(1.0, 1.0, 1.0, 1.0)
        shadow_fbo.depth_mask = False
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.DST_COLOR, moderngl.ZERO  # several shadows multiply
        self.floor_prog["clip_from_world"].write(clip)
        for g in drawn:
            if g.floor_vao is not None:
                g.floor_vao.render(moderngl.TRIANGLES)
        self.ctx.disable(moderngl.BLEND)
        shadow_fbo.depth_mask = True
        rgba = np.frombuffer(color.read(), np.float32).reshape(height, width, 4)
        z = np.frombuffer(zbuf.read(), np.float32).reshape(height, width)
        ratio = np.frombuffer(shadow.read(), np.float32).reshape(height, width, 4)[..., :3].copy()
        mask = rgba[..., 3] > 0.5
        return RenderResult(rgba[..., :3].copy(), mask, np.where(mask, z, np.inf).astype(np.float32), ratio,
                            tuple(g.obj.id for g in self.objects.values() if g.env is None))

    @current_context
    def release(self) -> None:
        """Free every GL resource (the context too when this renderer created it)."""
        for g in self.objects.values():
            g.release()
        if self._targets is not None:
            for res in self._targets[1:]:
                res.release()
        self._targets = None
        self.dfg.release()
        self.prefilter.prog.release()
        if self.own_ctx:
            self.ctx.release()
