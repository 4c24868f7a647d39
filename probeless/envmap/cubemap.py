"""Environment cubemaps seen from a virtual object (paper §4.7): textured coarse model, dense model on top.

Pass 1 renders the textured prism with depth testing. Pass 2 clears the depth buffer and renders
the dense model (points as round splats whose size falls with distance, or a vertex-coloured
mesh) plus any other virtual objects (flat-coloured spheres), depth-tested only among themselves:
the dense model lands *on top of* the coarse model regardless of depth, the paper's choice (it is
nearer and more detailed, and replaces walls it also captured). Points given normals are dropped where they
face away from the cube's centre or are seen nearly edge-on (``min_facing``): without the depth of the
surfaces in front of them, such splats show hidden surfaces (a table's sides through its unsampled top) as
dark specks. The brightness change Δ is added to
the dense colours only (the atlas already has it baked in by the texturer).

All colours are camera LDR units 0..1 (sRGB-encoded camera output / 255), as in the atlas; the map then
comes out in those units. With ``linear=True`` (:meth:`EnvmapRenderer.set_atlas`, :meth:`~EnvmapRenderer.set_dense`)
the atlas and the dense colours are instead float linear radiance, unbounded (the HDR expansion of
:mod:`probeless.hdr.coarse`): uploaded as float32, never clipped to 1 nor sRGB-decoded, and the map comes out in
linear radiance (give both models in the same units, and Δ = 0: it is in camera LDR units). Faces
follow :mod:`probeless.messages.lighting` (framebuffer texel (row, col) is cube texel [face, row, col]).
Known limit: other virtual objects are drawn over the coarse model too, so a wall never hides one
(exact in convex rooms).
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from probeless.coarse.atlas import AtlasLayout
from probeless.coarse.texels import coarse_mesh
from probeless.envmap.cube_util import face_buckets, ldr_colors, linear_radiance, prefilter, unit_sphere
from probeless.errors import ProbelessError
from probeless.geom.cube import cube_face_clip_from_world
from probeless.gl.context import create_context, current_context
from probeless.gl.programs import load_program, mat_bytes
from probeless.gl.textures import float_target, upload_texture

__all__ = ["EnvmapRenderer", "MIN_FACING", "SPLAT_COVER", "face_buckets", "ldr_colors", "linear_radiance", "prefilter",
           "unit_sphere"]  # the helpers live in probeless.envmap.cube_util
SHADERS = Path(__file__).with_name("shaders")
NEAR_M = 0.01
SPLAT_COVER = 1.5  # splat diameter / point spacing: round splats close a square lattice's gaps from sqrt(2) up
MIN_FACING = 0.1  # cos of the most grazing view of a dense point with a normal that is still drawn (84 deg)


class EnvmapRenderer:
    """Renders (6, S, S, 3) camera-LDR (or linear HDR) cubemaps from the textured coarse model, a dense model
    and spheres."""

    def __init__(self, layout: AtlasLayout, *, ctx: moderngl.Context | None = None):
        self.ctx = ctx or create_context()
        self.ctx.__enter__()  # current while its objects are made (another context may be current)
        self.layout = layout
        v, t, uv, _ = coarse_mesh(layout)
        self.coarse_prog = load_program(self.ctx, "cube_coarse", shader_dir=SHADERS, vertex="textured_mesh")
        self.dense_prog = load_program(self.ctx, "cube_dense", shader_dir=SHADERS)
        self.flat_prog = load_program(self.ctx, "cube_flat", shader_dir=SHADERS)
        self._buffers = [self.ctx.buffer(np.hstack([v, uv]).astype("f4").tobytes()),
                         self.ctx.buffer(np.asarray(t, "i4").tobytes())]
        self.coarse_vao = self.ctx.vertex_array(self.coarse_prog, [(self._buffers[0], "3f 2f", "in_position", "in_uv")],
                                                index_buffer=self._buffers[1])
        sv, st = unit_sphere()
        self._sphere = [self.ctx.buffer(sv.tobytes()), self.ctx.buffer(st.tobytes())]
        self.sphere_vao = self.ctx.vertex_array(self.flat_prog, [(self._sphere[0], "3f", "in_position")],
                                                index_buffer=self._sphere[1])
        lo, hi = layout.floorplan.min(axis=0), layout.floorplan.max(axis=0)
        self.far = 2.0 * (float(np.linalg.norm(hi - lo)) + layout.ceiling_height) + 10.0
        self.layout_padding = 2  # layout_atlas's default ring of texels around every rectangle
        self.atlas_tex = None
        self._alpha_tex = None  # the atlas's alpha (observed texels) when set_atlas was given one
        self.dense = None  # (vao, buffers, mode)
        self.dense_linear = False  # the dense colours are linear radiance (set_dense(..., linear=True))
        self._points = self._bucket_key = self._bucket_ibo = None  # points, and per-face index buckets
        self._fbos: dict[int, moderngl.Framebuffer] = {}

    @current_context
    def set_atlas(self, atlas: np.ndarray, linear: bool = False) -> None:
        """Upload the atlas image (H, W, 3|4) uint8 (or float 0..1), row 0 = top.

        ``linear``: the atlas is float linear radiance >= 0 (HDR), uploaded as float32 unchanged. An alpha
        channel (255 / 1 = observed directly) is kept for :meth:`observed_mask` only; it never dims the map.
        """
        img = np.asarray(atlas)
        want = (self.layout.height, self.layout.width)
        if img.ndim != 3 or img.shape[:2] != want or img.shape[2] not in (3, 4):
            raise ProbelessError(f"EnvmapRenderer.set_atlas: atlas is {img.shape}, the layout needs {want + (3,)} "
                                 f"or {want + (4,)}")
        if linear:
            img = linear_radiance(img[..., :3], "EnvmapRenderer.set_atlas")
        elif img.dtype != np.uint8:
            img = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
        self.atlas_tex = self._upload(img[..., :3], self.atlas_tex)
        alpha = np.asarray(atlas)[..., 3] if np.shape(atlas)[2] == 4 else None
        if alpha is None:
            if self._alpha_tex is not None:
                self._alpha_tex.release()
            self._alpha_tex = None
        else:
            seen = (alpha >= (128 if alpha.dtype == np.uint8 else 0.5)).astype(np.uint8) * np.uint8(255)
            self._alpha_tex = self._upload(np.repeat(seen[..., None], 3, axis=2), self._alpha_tex)

    def _upload(self, img: np.ndarray, tex):
        # mip levels beyond the padding ring would blend neighbouring surfaces' rectangles
        return upload_texture(self.ctx, img[::-1], tex, filter="trilinear", repeat=True,
                              max_mip_level=max(0, int(np.log2(max(1, self.layout_padding)))))

    @current_context
    def set_dense(self, points: np.ndarray, colors: np.ndarray, linear: bool = False,
                  normals: np.ndarray | None = None) -> None:
        """Dense model as coloured points (N, 3) world [m]; colours uint8 0..255 or float 0..1 camera LDR,
        or with ``linear`` float linear radiance >= 0 (HDR, never clamped); optional unit ``normals`` (N, 3)
        [world] (rows of 0 = unknown) let back-facing and edge-on points be dropped (module doc)."""
        p = np.asarray(points, "f4")
        if p.ndim != 2 or p.shape[1] != 3 or len(p) != len(colors):
            raise ProbelessError(f"EnvmapRenderer.set_dense: points {p.shape} and colours {np.shape(colors)} "
                                 f"must be (N, 3) each")
        n = np.zeros_like(p) if normals is None else np.asarray(normals, "f4")
        if n.shape != p.shape or not np.isfinite(n).all():
            raise ProbelessError(f"EnvmapRenderer.set_dense: normals {n.shape} must be finite and match the points "
                                 f"{p.shape}")
        self._set_dense(p, self._colors(colors, linear, "set_dense"), None, moderngl.POINTS, linear, n)
        self._points = p

    @current_context
    def set_dense_mesh(self, vertices: np.ndarray, triangles: np.ndarray, vertex_colors: np.ndarray,
                       linear: bool = False) -> None:
        """Dense model as a vertex-coloured triangle mesh (colours and ``linear`` as in :meth:`set_dense`)."""
        v, t = np.asarray(vertices, "f4"), np.asarray(triangles, "i4")
        if v.ndim != 2 or v.shape[1] != 3 or len(v) != len(vertex_colors) or t.ndim != 2 or t.shape[1] != 3:
            raise ProbelessError(f"EnvmapRenderer.set_dense_mesh: vertices {v.shape}, colours "
                                 f"{np.shape(vertex_colors)}, triangles {t.shape}")
        self._set_dense(v, self._colors(vertex_colors, linear, "set_dense_mesh"), t, moderngl.TRIANGLES, linear)

    @staticmethod
    def _colors(colors: np.ndarray, linear: bool, what: str) -> np.ndarray:
        if not linear:
            return ldr_colors(colors, what)
        c = linear_radiance(colors, what)
        if c.ndim != 2 or c.shape[1] != 3:
            raise ProbelessError(f"{what}: colours must be (N, 3), got {c.shape}")
        return c

    def _set_dense(self, p, c, tris, mode, linear: bool = False, normals=None) -> None:
        self.clear_dense()
        self.dense_linear = bool(linear)
        self._points, self._bucket_key, self._bucket_ibo = None, None, None
        if len(p) == 0 or (tris is not None and len(tris) == 0):
            return
        n = np.zeros_like(p) if normals is None else normals
        bufs = [self.ctx.buffer(np.hstack([p, c, n]).astype("f4").tobytes())]
        if tris is not None:
            bufs.append(self.ctx.buffer(tris.tobytes()))
        vao = self.ctx.vertex_array(self.dense_prog, [(bufs[0], "3f 3f 3f", "in_position", "in_color", "in_normal")],
                                    index_buffer=bufs[1] if tris is not None else None)
        self.dense = (vao, bufs, mode)

    def _point_buckets(self, position: np.ndarray) -> list[tuple[int, int]]:
        """(first, count) per face into an index buffer of per-face points; rebuilt when the position moves."""
        key = tuple(np.round(position, 6))
        if key != self._bucket_key:
            buckets = face_buckets(self._points, position)
            if self._bucket_ibo is not None:
                self._bucket_ibo[0].release()
                self._bucket_ibo[1].release()
            ibo = self.ctx.buffer(np.concatenate(buckets).astype("i4").tobytes())
            attrs = (self.dense[1][0], "3f 3f 3f", "in_position", "in_color", "in_normal")
            vao = self.ctx.vertex_array(self.dense_prog, [attrs], index_buffer=ibo)
            starts = np.cumsum([0] + [len(b) for b in buckets])
            self._bucket_ibo = (vao, ibo, [(int(starts[f]), len(buckets[f])) for f in range(6)])
            self._bucket_key = key
        return self._bucket_ibo[2]

    @current_context
    def clear_dense(self) -> None:
        """Forget the dense model."""
        if self.dense is not None:
            self.dense[0].release()
            for b in self.dense[1]:
                b.release()
        if getattr(self, "_bucket_ibo", None) is not None:
            self._bucket_ibo[0].release()
            self._bucket_ibo[1].release()
        self.dense, self._points, self._bucket_key, self._bucket_ibo = None, None, None, None

    def _fbo(self, size: int) -> moderngl.Framebuffer:
        if size not in self._fbos:
            self._fbos[size] = float_target(self.ctx, size, size)
        return self._fbos[size]

    @current_context
    def render(self, position, size: int = 256, delta=(0.0, 0.0, 0.0), dense: bool = True, splat_m: float = 0.02,
               max_splat_px: float = 64.0, spheres=(), finish: bool = True, min_facing: float = MIN_FACING
               ) -> np.ndarray:
        """(6, S, S, 3) float32 camera-LDR cubemap at ``position`` (3,) world [m] (linear radiance when the
        models were given ``linear``: module docstring).

        ``splat_m``: world diameter of a point splat (about the dense model's point spacing) [m];
        ``spheres``: other virtual objects as ``(centre (3,), radius [m], colour (3,) LDR 0..1)``;
        ``min_facing``: points with normals seen at a cosine below it are not drawn.
        """
        if self.atlas_tex is None:
            raise ProbelessError("EnvmapRenderer.render: no atlas yet (call set_atlas first)")
        return self._draw(self.atlas_tex, position, size, delta, dense, splat_m, max_splat_px, spheres, min_facing)

    @current_context
    def observed_mask(self, position, size: int = 256, dense: bool = True, splat_m: float = 0.02,
                      max_splat_px: float = 64.0, min_facing: float = MIN_FACING) -> np.ndarray:
        """(6, S, S) bool: texels of :meth:`render`'s map that show something observed: a coarse-model texel whose
        atlas alpha says observed directly, or, with ``dense``, a dense-model point (drawn as :meth:`render` draws
        it). Inpainted and never-seen texels: False; so is every coarse texel when :meth:`set_atlas` was given no
        alpha channel (e.g. an HDR atlas): then only the dense model counts (never more than is known).
        """
        if self.atlas_tex is None:
            raise ProbelessError("EnvmapRenderer.observed_mask: no atlas yet (call set_atlas first)")
        if self._alpha_tex is None:
            self._alpha_tex = upload_texture(self.ctx, np.zeros((1, 1, 3), np.uint8))
        faces = self._draw(self._alpha_tex, position, size, (0.0, 0.0, 0.0), dense, splat_m, max_splat_px, (),
                           min_facing, coverage=True)
        return faces.max(axis=3) > 0.5

    def _draw(self, atlas_tex, position, size, delta, dense, splat_m, max_splat_px, spheres, min_facing,
              coverage: bool = False) -> np.ndarray:
        pos = np.asarray(position, np.float64)
        if pos.shape != (3,) or not np.isfinite(pos).all():
            raise ProbelessError(f"EnvmapRenderer.render: position must be 3 finite numbers, got {position!r}")
        fbo = self._fbo(size)
        fbo.use()
        ctx = self.ctx
        ctx.disable(moderngl.CULL_FACE)
        ctx.enable(moderngl.PROGRAM_POINT_SIZE)
        atlas_tex.use(0)
        self.coarse_prog["atlas"] = 0
        dp = self.dense_prog
        for name, value in (("splat_px_m", splat_m * size / 2.0), ("max_px", float(max_splat_px)),
                            ("delta", tuple(float(x) for x in delta)), ("coverage", bool(coverage)),
                            ("eye", tuple(float(x) for x in pos)), ("min_facing", float(min_facing))):
            if name in dp:
                dp[name] = value
        out = np.empty((6, size, size, 3), np.float32)
        buckets = self._point_buckets(pos) if dense and self.dense is not None and self._points is not None else None
        for face, clip in enumerate(cube_face_clip_from_world(pos, size, NEAR_M, self.far)):
            m = mat_bytes(clip)
            fbo.clear(0.0, 0.0, 0.0, 1.0)
            ctx.enable(moderngl.DEPTH_TEST)
            self.coarse_prog["clip_from_world"].write(m)
            self.coarse_vao.render(moderngl.TRIANGLES)
            self._clear_depth(fbo)
            if dense and self.dense is not None:
                vao, _, mode = self.dense
                dp["clip_from_world"].write(m)
                if "round_splats" in dp:
                    dp["round_splats"] = mode == moderngl.POINTS
                if "linear_hdr" in dp:
                    dp["linear_hdr"] = self.dense_linear
                if buckets is None:
                    vao.render(mode)
                elif buckets[face][1]:
                    self._bucket_ibo[0].render(mode, vertices=buckets[face][1], first=buckets[face][0])
            for centre, radius, color in spheres:
                self.flat_prog["clip_from_world"].write(m)
                self.flat_prog["sphere"] = (*map(float, centre), float(radius))
                self.flat_prog["color"] = tuple(float(x) for x in color)
                self.sphere_vao.render(moderngl.TRIANGLES)
            out[face] = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(size, size, 4)[..., :3]
        return out

    def _clear_depth(self, fbo: moderngl.Framebuffer) -> None:
        """Reset the depth buffer, keeping the colour (pass 2 ignores the coarse model's depth)."""
        fbo.color_mask = (False, False, False, False)
        fbo.clear(depth=1.0)
        fbo.color_mask = (True, True, True, True)
        fbo.use()  # moderngl applies the colour mask when the framebuffer is bound

    @current_context
    def release(self) -> None:
        """Free the GL objects (not the context when it was passed in)."""
        self.clear_dense()
        for obj in [self.coarse_vao, self.sphere_vao, *self._buffers, *self._sphere, *self._fbos.values()]:
            obj.release()
        for tex in (self.atlas_tex, self._alpha_tex):
            if tex is not None:
                tex.release()
        self._fbos.clear()
