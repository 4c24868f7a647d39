"""GPU texturing of the coarse model's atlas from the fisheye (paper §4.3–4.4), moderngl headless.

:class:`AtlasTexturer` keeps the atlas in a float GL texture between frames (rgb in camera LDR
units 0..1, alpha = time the texel was last seen directly, -1 = never; never-seen texels start neutral grey,
:data:`~probeless.coarse.atlas.UNSEEN_GREY`) and runs, per frame:

1. :meth:`occlusion` - the visibility polygon from the fisheye's floor position drawn as a triangle
   fan into a floor-space mask, then turned into an atlas-space mask by a fragment pass (skipped,
   all visible, for a convex floorplan);
2. :meth:`update` - a fragment pass over every texel (ping-pong between two textures): project into
   the fisheye; visible texels take the fisheye colour, the others add the brightness change Δ.
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from probeless.cameras.omnidir import OmnidirModel
from probeless.coarse.atlas import UNSEEN_GREY, AtlasLayout
from probeless.coarse.texels import TexelMap
from probeless.coarse.visibility import is_convex, visibility_polygon
from probeless.errors import CalibrationError
from probeless.gl.context import create_context, current_context
from probeless.gl.programs import load_program, mat_bytes, set_uniforms
from probeless.gl.textures import upload_texture

SHADERS = Path(__file__).with_name("shaders")


def check_runtime_model(model) -> OmnidirModel:
    """The GPU projects with an ideal omnidir model: anything else must be undistorted first."""
    if not isinstance(model, OmnidirModel) or np.any(np.asarray(model.D) != 0):
        raise CalibrationError(f"the texturer needs the undistorted runtime model (omnidir, D = 0), got "
                               f"{type(model).__name__}: put a fisheye_undistort node before it")
    return model


class AtlasTexturer:
    """The coarse model's texture atlas on the GPU and the passes that update it."""

    def __init__(self, layout: AtlasLayout, texmap: TexelMap, *, fov_deg: float = 180.0,
                 ctx: moderngl.Context | None = None, occlusion_offset_texels: float = 1.5, occlusion: bool = True):
        self.layout, self.texmap = layout, texmap
        self.ctx = ctx or create_context()
        self.cos_half_fov = float(np.cos(np.radians(fov_deg) / 2))
        self.convex = is_convex(layout.floorplan)
        self.skip_occlusion = self.convex or not occlusion  # occlusion=False: the ablation "no occlusion handling"
        self.offset_m = occlusion_offset_texels / layout.texels_per_m
        ctx, size = self.ctx, (layout.width, layout.height)
        pos = np.concatenate([texmap.position, texmap.surface[..., None].astype(np.float32)], axis=2)
        nrm = np.concatenate([texmap.normal, np.zeros(texmap.surface.shape + (1,), np.float32)], axis=2)
        self.positions, self.normals = upload_texture(ctx, pos), upload_texture(ctx, nrm)
        blank = np.full((layout.height, layout.width, 4), UNSEEN_GREY, np.float32)
        blank[..., 3] = -1.0
        self.atlas = [upload_texture(ctx, blank), upload_texture(ctx, blank)]
        self.fbos = [ctx.framebuffer([t]) for t in self.atlas]
        self.current = 0
        self.occ = ctx.texture(size, 1, dtype="f1")
        self.occ_fbo = ctx.framebuffer([self.occ])
        lo, hi = layout.floorplan.min(axis=0), layout.floorplan.max(axis=0)
        margin = 4.0 / layout.texels_per_m
        self.mask_min, self.mask_size = lo - margin, (hi - lo) + 2 * margin
        mask_px = np.ceil(self.mask_size * layout.texels_per_m).astype(int)
        self.floor_mask = ctx.texture(tuple(int(v) for v in mask_px), 1, dtype="f1")
        self.floor_mask.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.floor_fbo = ctx.framebuffer([self.floor_mask])
        self.packed = ctx.texture(size, 4, dtype="f1")
        self.pack_fbo = ctx.framebuffer([self.packed])
        prog = lambda name, vert=None: load_program(ctx, name, shader_dir=SHADERS, vertex=vert)  # noqa: E731
        self.fan_prog = prog("visfan")
        self.occ_prog = prog("occlusion", "fullscreen")
        self.tex_prog = prog("texture", "fullscreen")
        self.pack_prog = prog("pack", "fullscreen")
        self.quads = {p: ctx.vertex_array(p, []) for p in (self.occ_prog, self.tex_prog, self.pack_prog)}
        self._fisheye: moderngl.Texture | None = None
        self.occ_fbo.use()
        self.occ_fbo.clear(1.0, 1.0, 1.0, 1.0)

    @current_context
    def occlusion(self, viewpoint_xy: np.ndarray) -> None:
        """Atlas-space visibility from ``viewpoint_xy`` (the fisheye's floor position) [m, world]."""
        if self.skip_occlusion:
            return  # the mask was cleared to "visible" once; a convex prism cannot occlude itself
        poly = visibility_polygon(self.layout.floorplan, np.asarray(viewpoint_xy, np.float64))
        fan = np.concatenate([np.asarray(viewpoint_xy, np.float64)[None], poly, poly[:1]]).astype("f4")
        vbo = self.ctx.buffer(fan.tobytes())
        vao = self.ctx.vertex_array(self.fan_prog, [(vbo, "2f", "in_xy")])
        set_uniforms(self.fan_prog, mask_min=tuple(self.mask_min), mask_size=tuple(self.mask_size))
        self.floor_fbo.use()
        self.floor_fbo.clear(0.0, 0.0, 0.0, 0.0)
        vao.render(moderngl.TRIANGLE_FAN)
        vao.release()
        vbo.release()
        self.positions.use(0)
        self.normals.use(1)
        self.floor_mask.use(2)
        set_uniforms(self.occ_prog, positions=0, normals=1, floor_mask=2, mask_min=tuple(self.mask_min),
                     mask_size=tuple(self.mask_size), offset_m=self.offset_m)
        self.occ_fbo.use()
        self.quads[self.occ_prog].render(moderngl.TRIANGLES, vertices=3)

    def _upload_fisheye(self, image: np.ndarray) -> moderngl.Texture:
        self._fisheye = upload_texture(self.ctx, np.asarray(image, np.uint8), self._fisheye, filter="linear")
        return self._fisheye

    @current_context
    def update(self, image: np.ndarray, model: OmnidirModel, world_from_fisheye: np.ndarray,
               delta: np.ndarray = (0.0, 0.0, 0.0), t_s: float = 0.0) -> None:
        """Texture every visible texel from ``image`` (uint8 RGB of the runtime model); Δ for the rest."""
        check_runtime_model(model)
        if image.shape[:2] != (model.height, model.width):
            raise CalibrationError(f"fisheye image is {image.shape[1]}x{image.shape[0]}, its camera_info says "
                                   f"{model.width}x{model.height}")
        fisheye = self._upload_fisheye(image)
        src, dst = self.current, 1 - self.current
        self.positions.use(0)
        self.atlas[src].use(1)
        self.occ.use(2)
        fisheye.use(3)
        self.tex_prog["fisheye_from_world"].write(mat_bytes(np.linalg.inv(world_from_fisheye)))
        self.tex_prog["K"].write(mat_bytes(model.K))
        set_uniforms(self.tex_prog, positions=0, previous=1, occlusion=2, fisheye=3, xi=float(model.xi),
                     cos_half_fov=self.cos_half_fov, image_size=(float(model.width), float(model.height)),
                     delta=tuple(float(d) for d in np.asarray(delta).reshape(3)), t_s=float(t_s))
        self.fbos[dst].use()
        self.quads[self.tex_prog].render(moderngl.TRIANGLES, vertices=3)
        self.current = dst

    @current_context
    def read_atlas(self) -> tuple[np.ndarray, np.ndarray]:
        """(rgb (H, W, 3) float32 camera LDR units, last_seen_s (H, W) float32, -1 = never) from the GPU."""
        raw = np.frombuffer(self.atlas[self.current].read(), np.float32)
        raw = raw.reshape(self.layout.height, self.layout.width, 4)
        return raw[..., :3].copy(), raw[..., 3].copy()

    @current_context
    def write_atlas(self, rgb: np.ndarray, last_seen_s: np.ndarray) -> None:
        """Replace the atlas (e.g. with inpainted texels filled in)."""
        data = np.concatenate([rgb, last_seen_s[..., None]], axis=2).astype(np.float32)
        self.atlas[self.current].write(np.ascontiguousarray(data).tobytes())

    @current_context
    def read_packed(self) -> np.ndarray:
        """(H, W, 4) uint8: rgb clamped to 0..255, a = 255 where observed directly (the published atlas)."""
        self.atlas[self.current].use(0)
        set_uniforms(self.pack_prog, atlas=0)
        self.pack_fbo.use()
        self.quads[self.pack_prog].render(moderngl.TRIANGLES, vertices=3)
        raw = np.frombuffer(self.pack_fbo.read(components=4, alignment=1), np.uint8)
        return raw.reshape(self.layout.height, self.layout.width, 4)

    @current_context
    def read_occlusion(self) -> np.ndarray:
        """(H, W) bool atlas-space visibility of the last :meth:`occlusion` call."""
        raw = np.frombuffer(self.occ.read(alignment=1), np.uint8)
        return raw.reshape(self.layout.height, self.layout.width) > 127

    @current_context
    def release(self) -> None:
        """Free the GL objects (the context too if this texturer created it)."""
        for obj in (*self.quads.values(), *self.atlas, *self.fbos, self.occ, self.occ_fbo, self.floor_mask,
                    self.floor_fbo, self.packed, self.pack_fbo, self.positions, self.normals, self._fisheye):
            if obj is not None:
                obj.release()
