"""Lighting nodes of the 360° video IBL pipeline (paper 002): inverse tone mapping and diffuse maps.

``itmo``: ``image`` (rgb8 equirect LDR frame) -> ``hdr`` (rgbf16, full resolution) and ``hdr_small``
(rgbf32, area-averaged to ``small_size``: what ``diffuse_map`` needs, so the full frame does not
cross processes twice). Operators: ``paper`` (Eq. 1-3 on the stored values), ``landis``, ``akyuz``,
``banterle`` (on gamma-decoded values with ``linearize``), ``none`` (sRGB decode only), ``ldr``
(values / 255 as they are). ``gpu`` runs paper, landis, none and ldr in a fragment shader;
akyuz and banterle always run numpy (:mod:`probeless.pano.itmo`).

``diffuse_map``: ``hdr`` (rgbf16/rgbf32 equirect; used as is when it is ``in_size``, else
area-averaged) -> ``diffuse`` (rgbf32 ``out_size``): Algorithm 1 on the GPU (``gpu``), the numpy
weight-matrix product (``matmul``), 9 SH coefficients (``sh9``, Ramamoorthi-Hanrahan) or ``fast``
(:func:`probeless.pano.diffuse_fast.diffuse_map_fast`: Algorithm 1 by FFT on a 256x128 average, the brightest
texels summed from the full frame; within 1 % of the exact map on the HDR panoramas; the shipped graph's
method, fed the full frame).
``weights: moments`` (gpu only) needs the full frame (``itmo``'s ``hdr``, not ``hdr_small``) and
is near exact (see :mod:`probeless.pano.gpu_diffuse` and ``probeless pano diffuse``).
Both keep the input header (stamp, frame_id).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import SchemaError
from probeless.messages.sensor import Image
from probeless.pano.diffuse import diffuse_map, sh9_irradiance_map
from probeless.pano.diffuse_fast import diffuse_map_fast
from probeless.pano.expand import area_resize, expand_cpu
from probeless.pano.gpu_itmo import GPU_OPERATORS
from probeless.runtime import Node, param

OPERATORS = ("paper", "landis", "akyuz", "banterle", "none", "ldr")


def equirect_size(key: str):
    """A param check: ``key`` is [W, H] with W == 2 H (an equirectangular size)."""
    def check(size: tuple[int, ...]) -> str | None:
        return None if size[0] == 2 * size[1] else f"{key} must be [2H, H], got {list(size)}"
    return check


def check_image(node: str, name: str, msg: Image, encodings: tuple[str, ...]) -> np.ndarray:
    """``msg.data`` if ``msg`` is an equirect (W == 2 H) image in one of ``encodings``, else SchemaError."""
    if msg.encoding not in encodings:
        raise SchemaError(f"{node}: input {name!r} must be {' or '.join(encodings)}, got {msg.encoding!r}")
    if msg.width != 2 * msg.height:
        raise SchemaError(f"{node}: input {name!r} is {msg.width}x{msg.height}, not an equirectangular 2:1 image")
    return msg.data


class InverseToneMap(Node):
    """``image`` (rgb8) -> ``hdr`` (rgbf16) + ``hdr_small`` (rgbf32), see the module docstring."""

    INPUTS = {"image": Image}
    OUTPUTS = {"hdr": Image, "hdr_small": Image}

    @dataclass(frozen=True)
    class Params:
        operator: str = param("paper", choices=OPERATORS, doc="inverse tone mapping operator")
        gpu: bool = param(True, doc="run on the GPU (paper, landis, none, ldr; akyuz and banterle are numpy)")
        linearize: bool = param(True, doc="landis/akyuz/banterle: decode value ** decode_gamma first")
        decode_gamma: float = param(2.2, min=0.1, max=10.0, doc="display gamma decoded with linearize")
        max_lum: float = param(10.0, min=1e-3, max=1e4, doc="landis/akyuz/banterle: HDR luminance of LDR white")
        landis_threshold: float = param(0.5, min=0.0, max=0.99, doc="landis: luminance where expansion starts")
        landis_alpha: float = param(2.0, min=0.01, max=100.0, doc="landis: blend exponent")
        akyuz_gamma: float = param(1.0, min=0.01, max=100.0, doc="akyuz: exponent of the normalised luminance")
        banterle_l_white: float = param(10.0, min=1e-3, max=1e4, doc="banterle: inverse Reinhard white point")
        banterle_threshold: float = param(0.9, min=0.0, max=1.0, doc="banterle: luminance of expand-map seeds")
        banterle_sigma_frac: float = param(0.02, min=1e-4, max=1.0, doc="banterle: expand-map blur / width")
        small_size: tuple[int, ...] = param((128, 64), length=2, min=1, check=equirect_size("small_size"),
                                            doc="size (W, H) of hdr_small [px]; W == 2 H")
        full: bool = param(True, doc="publish the full-resolution hdr (false: hdr_small only)")

    def setup(self) -> None:
        p = self.params
        self.op_params = {"landis": dict(max_lum=p.max_lum, threshold=p.landis_threshold, alpha=p.landis_alpha),
                          "akyuz": dict(max_lum=p.max_lum, gamma=p.akyuz_gamma),
                          "banterle": dict(max_lum=p.max_lum, l_white=p.banterle_l_white,
                                           threshold=p.banterle_threshold, sigma_frac=p.banterle_sigma_frac),
                          }.get(p.operator, {})
        self.gpu = None
        if p.gpu and p.operator in GPU_OPERATORS:
            from probeless.pano.gpu_itmo import GpuItmo

            self.gpu = GpuItmo(operator=p.operator, linearize=p.linearize, decode_gamma=p.decode_gamma,
                               **self.op_params)
        elif p.gpu:
            self.ctx.log.info("itmo: %s has no GPU version; running it with numpy", p.operator)

    def on_input(self, name: str, msg: Image) -> None:
        p = self.params
        rgb8 = check_image("itmo", name, msg, ("rgb8",))
        if msg.width < p.small_size[0]:
            raise SchemaError(f"itmo: input {name!r} is {msg.width}x{msg.height}, smaller than small_size "
                              f"{list(p.small_size)}")
        if self.gpu is not None:
            with self.ctx.timed("itmo"):
                self.gpu.expand(rgb8)
                full = self.gpu.read_full(np.float16) if p.full else None
            with self.ctx.timed("downsample"):
                small = self.gpu.read_small(p.small_size)
        else:
            with self.ctx.timed("itmo"):
                hdr = expand_cpu(rgb8, p.operator, linearize=p.linearize, decode_gamma=p.decode_gamma,
                                 **self.op_params)
                full = hdr.astype(np.float16) if p.full else None
            with self.ctx.timed("downsample"):
                small = area_resize(hdr, p.small_size)
        if full is not None:
            self.ctx.publish("hdr", Image(msg.header, full, "rgbf16"))
        self.ctx.publish("hdr_small", Image(msg.header, np.ascontiguousarray(small, np.float32), "rgbf32"))

    def close(self) -> None:
        if getattr(self, "gpu", None) is not None:
            self.gpu.release()


class DiffuseMap(Node):
    """``hdr`` (rgbf16/rgbf32) -> ``diffuse`` (rgbf32 out_size), see the module docstring."""

    INPUTS = {"hdr": Image}
    OUTPUTS = {"diffuse": Image}

    @dataclass(frozen=True)
    class Params:
        method: str = param("gpu", choices=("gpu", "matmul", "sh9", "fast"),
                            doc="Algorithm 1 on the GPU, numpy weight matrix, 9 SH coefficients, or fast: Algorithm 1 "
                                "by FFT on a 256x128 average with the brightest texels summed from the full frame "
                                "(probeless.pano.diffuse_fast; give it the full frame)")
        out_size: tuple[int, ...] = param((32, 16), length=2, min=1, check=equirect_size("out_size"),
                                          doc="diffuse map size (W, H) [px]; W == 2 H")
        in_size: tuple[int, ...] = param((128, 64), length=2, min=1, check=equirect_size("in_size"),
                                         doc="size (W, H) the input is area-averaged to [px]; W == 2 H")
        weights: str = param("subtexel", choices=("subtexel", "paper", "moments"), doc="gpu: texel weights "
                             "integrated over sub-texels (as matmul), the paper's cos(latitude) * cos(angle), or "
                             "radiance moments of the full frame (near exact; needs hdr >= 4 x in_size)")

    def setup(self) -> None:
        p = self.params
        self.out_size, self.in_size = tuple(p.out_size), tuple(p.in_size)
        self.gpu = None
        if p.method == "gpu":
            from probeless.pano.gpu_diffuse import GpuDiffuse

            self.gpu = GpuDiffuse(out_size=self.out_size, in_size=self.in_size, weights=p.weights)

    def on_input(self, name: str, msg: Image) -> None:
        data = check_image("diffuse_map", name, msg, ("rgbf32", "rgbf16"))
        if msg.width < self.in_size[0]:
            raise SchemaError(f"diffuse_map: input {name!r} is {msg.width}x{msg.height}, smaller than in_size "
                              f"{list(self.in_size)}")
        if self.params.method == "gpu" and self.params.weights == "moments" and msg.width < 4 * self.in_size[0]:
            raise SchemaError(f"diffuse_map: weights 'moments' needs input {name!r} of at least 4 x in_size "
                              f"{list(self.in_size)} (the full frame, not hdr_small), got {msg.width}x{msg.height}")
        with self.ctx.timed("diffuse"):
            if self.gpu is not None:
                out = self.gpu.apply(data)  # the GPU area-averages when the size differs
            elif self.params.method == "fast":
                out = diffuse_map_fast(data, self.out_size)
            elif self.params.method == "matmul":
                out = diffuse_map(area_resize(data, self.in_size), self.out_size, in_size=self.in_size)
            else:
                out = sh9_irradiance_map(area_resize(data, self.in_size), self.out_size)
        self.ctx.publish("diffuse", Image(msg.header, np.ascontiguousarray(out, np.float32), "rgbf32"))

    def close(self) -> None:
        if getattr(self, "gpu", None) is not None:
            self.gpu.release()
