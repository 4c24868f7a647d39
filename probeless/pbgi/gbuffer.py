"""The virtual objects' G-buffer (paper 001 §5.2) and its cone mip-map (§5.2.1, Figure 6).

:class:`GBufferRenderer` rasterises placed meshes with their materials into a :class:`GBuffer` (world position,
normal facing the camera, base colour, roughness, metalness, BRDF model, object index; maps sampled by the mesh UVs).
:func:`pixel_pyramid` turns its covered pixels into the flat, Z-ordered :data:`GPIXEL_DTYPE` records the micro-buffer
programs read: level 0 are the pixels themselves; a pixel of level i > 0 merges the up to four non-empty pixels
of level i - 1 it covers, keeping a *cone* of their normals (axis, half-angle: the paper's mipmapping operator) and
a *sphere* of their positions (mean, radius), so culling and refinement at coarse levels stay conservative.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import PbgiError
from probeless.geom.projection import clip_from_camera
from probeless.gl.programs import load_program, mat_bytes, set_uniforms
from probeless.gl.textures import upload_texture

SHADERS = Path(__file__).with_name("shaders")
ANGLE_SLACK = 1e-3  # [rad] widens coarse normal cones past float32 rounding of the normals (acos near 1)

GPIXEL_DTYPE = np.dtype([("position", "<f4", (3,)), ("rho", "<f4"), ("normal", "<f4", (3,)), ("gamma", "<f4"),
                         ("first", "<u4"), ("count", "<u4"), ("level", "<u4"), ("slot", "<u4")])


@dataclass(frozen=True)
class GBuffer:
    """Per camera pixel (row, col); only ``mask`` pixels are meaningful."""

    mask: np.ndarray       # (H, W) bool, an object covers the pixel
    position: np.ndarray   # (H, W, 3) float32 world position [m]
    normal: np.ndarray     # (H, W, 3) float32 unit normal, world, facing the camera
    base_color: np.ndarray  # (H, W, 3) float32 linear base colour
    roughness: np.ndarray  # (H, W) float32 perceptual roughness [0..1]
    metalness: np.ndarray  # (H, W) float32 [0..1]
    model: np.ndarray      # (H, W) int32 BRDF model id (probeless.pbgi.materials.MODEL_IDS)
    object_index: np.ndarray  # (H, W) int32 index of the object, -1 where uncovered
    depth: np.ndarray      # (H, W) float32 camera z [m]; inf where uncovered


@dataclass(frozen=True)
class Pyramid:
    """The G-buffer's covered pixels as mip levels of :data:`GPIXEL_DTYPE` records, level 0 first."""

    records: np.ndarray    # GPIXEL_DTYPE, levels concatenated (level 0: the pixels, Z-ordered)
    offsets: np.ndarray    # (levels + 1,) start of each level in records
    rows: np.ndarray       # (N0,) image row of each level-0 record
    cols: np.ndarray       # (N0,) image column
    below: np.ndarray      # (N_top,) level-0 pixels under each top-level record

    @property
    def levels(self) -> int:
        return len(self.offsets) - 1

    @property
    def n_pixels(self) -> int:
        return int(self.offsets[1])


def _morton2(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    def spread(v):
        v = v.astype(np.uint64) & np.uint64(0xFFFF)
        for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
            v = (v | (v << np.uint64(shift))) & np.uint64(mask)
        return v
    return spread(cols) | (spread(rows) << np.uint64(1))


def pixel_pyramid(mask: np.ndarray, position: np.ndarray, normal: np.ndarray, levels: int) -> Pyramid:
    """The :class:`Pyramid` of the ``mask`` pixels with ``levels`` levels above level 0 (tiles of 2^levels px)."""
    rows, cols = np.nonzero(mask)
    if rows.size == 0:
        raise PbgiError("pixel_pyramid: the G-buffer is empty (no object pixel in view)")
    code = _morton2(rows, cols)
    order = np.argsort(code, kind="stable")
    rows, cols, code = rows[order], cols[order], code[order]
    pos = position[rows, cols].astype(np.float64)
    nrm = normal[rows, cols].astype(np.float64)
    n0 = rows.size
    weight = np.ones(n0)
    rho, gamma = np.zeros(n0), np.zeros(n0)
    parts = [(pos, rho, nrm, gamma, np.zeros(n0, np.int64), np.zeros(n0, np.int64))]
    offsets = [0, n0]
    below = np.ones(n0, np.int64)
    for lev in range(1, levels + 1):
        key = code >> np.uint64(2)
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        cnt = np.diff(np.r_[starts, key.size])
        p_pos, p_rho, p_nrm, p_gam = parts[-1][:4]
        wsum = np.add.reduceat(weight, starts)
        c_pos = np.add.reduceat(p_pos * weight[:, None], starts) / wsum[:, None]
        grp = np.repeat(np.arange(starts.size), cnt)
        c_rho = np.maximum.reduceat(np.linalg.norm(p_pos - c_pos[grp], axis=1) + p_rho, starts) * (1 + 1e-6) + 1e-7
        axis = np.add.reduceat(p_nrm * weight[:, None], starts)
        ln = np.linalg.norm(axis, axis=1, keepdims=True)
        axis = np.where(ln > 1e-9, axis / np.maximum(ln, 1e-300), p_nrm[starts])
        ang = np.arccos(np.clip((p_nrm * axis[grp]).sum(1), -1, 1)) + p_gam
        c_gam = np.minimum(np.maximum.reduceat(ang, starts) + ANGLE_SLACK, np.pi)
        first = offsets[-2] + starts
        parts.append((c_pos, c_rho, axis, c_gam, first, cnt))
        offsets.append(offsets[-1] + starts.size)
        weight, code, below = wsum, key[starts], np.add.reduceat(below, starts)
    rec = np.zeros(offsets[-1], GPIXEL_DTYPE)
    for lev, (p, r, nv, g, first, cnt) in enumerate(parts):
        s = slice(offsets[lev], offsets[lev + 1])
        rec["position"][s], rec["rho"][s], rec["normal"][s], rec["gamma"][s] = p, r, nv, g
        rec["first"][s], rec["count"][s], rec["level"][s] = first, cnt, lev
    rec["slot"][:n0] = np.arange(n0)
    return Pyramid(rec, np.asarray(offsets, np.int64), rows, cols, below)


class GBufferRenderer:
    """Rasterises objects (``(mesh, brdf)`` pairs: a placed mesh and a :class:`~probeless.pbgi.materials.Brdf`)
    into a :class:`GBuffer`."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.prog = load_program(ctx, "pbgi_gbuffer", shader_dir=SHADERS)
        self._draws: list = []
        self._fbo = None

    def set_objects(self, objects) -> None:
        """Upload ``objects`` [(mesh, brdf)], replacing the previous ones."""
        from probeless.pbgi.materials import MODEL_IDS

        self.release_objects()
        for mesh, brdf in objects:
            uv = mesh.uvs if getattr(mesh, "uvs", None) is not None else np.zeros((len(mesh.vertices), 2))
            maps = (brdf.base_color_map, brdf.roughness_map, brdf.metalness_map)
            if any(m is not None for m in maps) and getattr(mesh, "uvs", None) is None:
                raise PbgiError("a material has texture maps but its mesh has no UVs")
            data = np.hstack([mesh.vertices, mesh.normals, uv]).astype("f4")
            vbo = self.ctx.buffer(data.tobytes())
            ibo = self.ctx.buffer(mesh.triangles.astype("i4").tobytes())
            vao = self.ctx.vertex_array(self.prog, [(vbo, "3f 3f 2f", "in_position", "in_normal", "in_uv")],
                                        index_buffer=ibo)
            tex = [None if m is None else upload_texture(self.ctx, np.asarray(m, np.float32), filter="linear",
                                                         repeat=True) for m in maps]
            self._draws.append((vao, vbo, ibo, tex, brdf, MODEL_IDS[brdf.model]))

    def _target(self, width: int, height: int):
        if self._fbo is None or self._fbo[0] != (width, height):
            if self._fbo is not None:
                for r in self._fbo[1:]:
                    r.release()
            texs = [self.ctx.texture((width, height), 4, dtype="f4") for _ in range(4)]
            depth = self.ctx.depth_texture((width, height))
            self._fbo = ((width, height), self.ctx.framebuffer(texs, depth), depth, *texs)
        return self._fbo[1], self._fbo[2], self._fbo[3:]

    def render(self, K: np.ndarray, world_from_camera: np.ndarray, width: int, height: int, near: float = 0.02,
               far: float = 100.0) -> GBuffer:
        """The G-buffer seen from ``world_from_camera`` (OpenCV axes) through pinhole ``K``."""
        fbo, depth_tex, texs = self._target(width, height)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        camera_from_world = np.linalg.inv(world_from_camera)
        self.prog["clip_from_world"].write(mat_bytes(clip_from_camera(K, width, height, near, far)
                                                     @ camera_from_world))
        for i, (vao, _, _, tex, brdf, model) in enumerate(self._draws):
            for unit, t in enumerate(tex):
                if t is not None:
                    t.use(unit)
            set_uniforms(self.prog, camera_position=tuple(world_from_camera[:3, 3]),
                         base_color=tuple(float(c) for c in brdf.base_color), roughness=float(brdf.roughness),
                         metalness=float(brdf.metalness), model=model, object_index=i, base_map=0, roughness_map=1,
                         metalness_map=2, has_base_map=tex[0] is not None, has_roughness_map=tex[1] is not None,
                         has_metalness_map=tex[2] is not None)
            vao.render(moderngl.TRIANGLES)
        pos, nrm, base, par = (np.frombuffer(t.read(), np.float32).reshape(height, width, 4) for t in texs)
        mask = pos[..., 3] > 0.5
        z = (camera_from_world[:3, :3] @ pos[..., :3].reshape(-1, 3).T).T.reshape(height, width, 3)[..., 2]
        z = z + camera_from_world[2, 3]
        return GBuffer(mask, pos[..., :3].copy(), nrm[..., :3].copy(), base[..., :3].copy(), base[..., 3].copy(),
                       par[..., 0].copy(), np.rint(par[..., 1]).astype(np.int32),
                       np.rint(par[..., 2]).astype(np.int32) - 1, np.where(mask, z, np.inf).astype(np.float32))

    def release_objects(self) -> None:
        for vao, vbo, ibo, tex, _, _ in self._draws:
            for r in (vao, vbo, ibo, *[t for t in tex if t is not None]):
                r.release()
        self._draws = []

    def release(self) -> None:
        self.release_objects()
        if self._fbo is not None:
            for r in self._fbo[1:]:
                r.release()
            self._fbo = None
