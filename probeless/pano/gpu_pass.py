"""Shared GL plumbing of the panorama GPU passes: one context, full-screen fragment passes, read-back.

Every pass draws one triangle over a float32 RGBA target and reads it back; fragment shaders
address texels with ``gl_FragCoord`` (the shared ``fullscreen`` vertex shader of :mod:`probeless.gl`).
Inputs go up with :func:`probeless.gl.textures.upload_texture`: texture row 0 is image row 0 and
framebuffer row 0 is the first row read back, so arrays go up and come down without flips.
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import ProbelessError
from probeless.gl.context import create_context, current_context
from probeless.gl.programs import load_program, set_uniforms

SHADERS = Path(__file__).with_name("shaders")


class GpuPasses:
    """Owns (or borrows) a GL context, compiled programs and cached float targets by size."""

    def __init__(self, ctx: moderngl.Context | None = None):
        self.own_ctx = ctx is None
        self.ctx = ctx or create_context()
        self.ctx.__enter__()  # subclasses create GL objects in __init__: in this context, not the last current one
        self._programs: dict[tuple, moderngl.Program] = {}
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        self._targets: dict[tuple[str, int, int], moderngl.Framebuffer] = {}

    @staticmethod
    def _key(name: str, defines: dict | None) -> tuple:
        return name, tuple(sorted((defines or {}).items()))

    def program(self, name: str, **defines) -> moderngl.Program:
        """The program ``shaders/NAME.frag.glsl`` with the full-screen vertex shader, compiled once."""
        key = self._key(name, defines)
        if key not in self._programs:
            prog = load_program(self.ctx, name, defines or None, shader_dir=SHADERS, vertex="fullscreen")
            self._programs[key] = prog
            self._vaos[key] = self.ctx.vertex_array(prog, [])
        return self._programs[key]

    def target(self, name: str, width: int, height: int, attachments: int = 1) -> moderngl.Framebuffer:
        """The cached framebuffer of pass ``name`` at ``width`` x ``height`` with ``attachments`` RGBA32F
        colour textures (one per pass, so a pass never draws into a texture it reads)."""
        key = (name, int(width), int(height))
        if key not in self._targets:
            texs = [self.ctx.texture(key[1:], 4, dtype="f4") for _ in range(attachments)]
            for tex in texs:
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._targets[key] = self.ctx.framebuffer(texs)
        return self._targets[key]

    def draw(self, name: str, size: tuple[int, int], textures: dict[str, moderngl.Texture],
             defines: dict | None = None, attachments: int = 1, **uniforms) -> moderngl.Framebuffer:
        """Run program ``name`` over a ``size`` (W, H) target with ``textures`` bound by sampler name."""
        prog = self.program(name, **(defines or {}))
        for unit, (sampler, tex) in enumerate(textures.items()):
            tex.use(unit)
            uniforms[sampler] = unit
        set_uniforms(prog, **uniforms)
        fbo = self.target(name, *size, attachments)
        fbo.use()
        self._vaos[self._key(name, defines)].render(moderngl.TRIANGLES, vertices=3)
        return fbo

    @staticmethod
    def read(fbo: moderngl.Framebuffer, dtype=np.float32) -> np.ndarray:
        """(H, W, 3) rgb of a target as float32 or float16 (the driver converts; half is half the bytes)."""
        w, h = fbo.size
        half = np.dtype(dtype) == np.float16
        raw = fbo.read(components=3, dtype="f2" if half else "f4", alignment=1)
        return np.frombuffer(raw, np.float16 if half else np.float32).reshape(h, w, 3).copy()

    @current_context
    def area_downsample(self, tex: moderngl.Texture, size: tuple[int, int]) -> moderngl.Framebuffer:
        """Area-average ``tex`` down to ``size`` (W, H) (cv2.INTER_AREA); the result's target."""
        (sw, sh), (w, h) = tex.size, (int(size[0]), int(size[1]))
        if not (1 <= w <= sw and 1 <= h <= sh):
            raise ProbelessError(f"area downsample: {sw}x{sh} cannot be reduced to {w}x{h}")
        return self.draw("area", (w, h), {"src": tex}, scale=(sw / w, sh / h))

    @current_context
    def release(self) -> None:
        """Free the GL objects (the context too if this object created it)."""
        attachments = [tex for fbo in self._targets.values() for tex in fbo.color_attachments]
        for obj in (*self._vaos.values(), *self._programs.values(), *self._targets.values(), *attachments):
            obj.release()
        self._vaos.clear(), self._programs.clear(), self._targets.clear()
        if self.own_ctx:
            self.ctx.release()
