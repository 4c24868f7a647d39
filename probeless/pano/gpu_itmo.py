"""Inverse tone mapping on the GPU (paper 002 Sec. 4: "easily and efficiently implemented on the GPU").

:class:`GpuItmo` uploads an 8-bit frame, expands it per pixel in a fragment shader into a float32
texture and optionally area-averages that texture down (the small frame the diffuse map is built
from), reading back what is asked for. Per-pixel operators run here: ``paper`` (Eq. 1-3 exactly,
on the stored values / 255, as :func:`probeless.pano.itmo.paper_itmo`), ``landis``, ``none`` (sRGB
decode to linear) and ``ldr`` (values / 255 as they are). Akyuz (needs the frame's luminance range)
and Banterle (needs a blurred expand map) stay numpy (:mod:`probeless.pano.itmo`).
"""

from __future__ import annotations

import moderngl
import numpy as np

from probeless.errors import ProbelessError
from probeless.gl.context import current_context
from probeless.gl.textures import upload_texture
from probeless.pano.gpu_pass import GpuPasses

GPU_OPERATORS = {"paper": 0, "landis": 1, "none": 2, "ldr": 3}


class GpuItmo(GpuPasses):
    """Per-pixel inverse tone mapping of rgb8 frames on the GPU (see the module docstring).

    ``params`` are the Landis parameters (``max_lum``, ``threshold``, ``alpha``) and, for Landis,
    ``linearize`` / ``decode_gamma`` (decode ``value ** decode_gamma`` first); others ignore them.
    """

    def __init__(self, ctx: moderngl.Context | None = None, operator: str = "paper", *, max_lum: float = 10.0,
                 threshold: float = 0.5, alpha: float = 2.0, linearize: bool = False, decode_gamma: float = 2.2):
        if operator not in GPU_OPERATORS:
            raise ProbelessError(f"GpuItmo: no GPU version of operator {operator!r}; GPU operators: "
                                 f"{', '.join(GPU_OPERATORS)}")
        if not 0.0 <= threshold < 1.0:
            raise ProbelessError(f"GpuItmo: landis threshold must be in [0, 1), got {threshold}")
        super().__init__(ctx)
        self.operator = operator
        self.uniforms = dict(op=GPU_OPERATORS[operator], max_lum=float(max_lum), threshold=float(threshold),
                             alpha=float(alpha), linearize=bool(linearize), decode_gamma=float(decode_gamma))
        self._frame: moderngl.Texture | None = None
        self._hdr: moderngl.Framebuffer | None = None

    def _upload(self, rgb8: np.ndarray) -> moderngl.Texture:
        a = np.asarray(rgb8)
        if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] != 3:
            raise ProbelessError(f"GpuItmo: expected an (H, W, 3) uint8 frame, got {a.dtype} {a.shape}")
        self._frame = upload_texture(self.ctx, a, self._frame)
        return self._frame

    @current_context
    def expand(self, rgb8: np.ndarray) -> None:
        """Upload the (H, W, 3) uint8 ``rgb8`` and expand it into the HDR target (stays on the GPU)."""
        frame = self._upload(rgb8)
        self._hdr = self.draw("itmo", frame.size, {"ldr": frame}, **self.uniforms)

    @current_context
    def read_full(self, dtype=np.float32) -> np.ndarray:
        """(H, W, 3) HDR frame of the last :meth:`expand`, as float32 or float16."""
        return self.read(self._expanded(), dtype)

    @current_context
    def read_small(self, small_size: tuple[int, int]) -> np.ndarray:
        """(h, w, 3) float32 area average of the last :meth:`expand` at ``small_size`` (w, h)."""
        return self.read(self.area_downsample(self._expanded().color_attachments[0], small_size))

    def run(self, rgb8: np.ndarray, small_size: tuple[int, int] | None = None, dtype=np.float32,
            full: bool = True) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(HDR frame of ``dtype`` or None unless ``full``, its area average at ``small_size`` or None)."""
        self.expand(rgb8)
        return (self.read_full(dtype) if full else None,
                self.read_small(small_size) if small_size is not None else None)

    def _expanded(self) -> moderngl.Framebuffer:
        if self._hdr is None:
            raise ProbelessError("GpuItmo: nothing expanded yet (call expand first)")
        return self._hdr

    def apply(self, rgb8: np.ndarray) -> np.ndarray:
        """(H, W, 3) float32 HDR frame of the (H, W, 3) uint8 ``rgb8``."""
        return self.run(rgb8)[0]

    @current_context
    def release(self) -> None:
        """Free the GL objects (the context too if this object created it)."""
        if self._frame is not None:
            self._frame.release()
            self._frame = None
        self._hdr = None
        super().release()
