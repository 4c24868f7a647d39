"""Diffuse radiance maps on the GPU: paper 002 Algorithm 1, one fragment per output texel.

The HDR frame is area-averaged on the GPU to ``in_size`` (skipped when it already has that size),
then every output texel loops over every input texel (``O(N^4)`` in the height, as the paper's):
``D(n) = sum w_i(n) L_i / sum w_i(n)`` with ``w_i(n)`` the integral of ``max(0, n . w)`` over input
texel ``i``. ``weights="subtexel"`` (default) integrates like :func:`probeless.pano.diffuse.diffuse_map`
(``sub x sub`` sub-texels where the horizon of ``n`` cuts the texel, the exact integral elsewhere),
so the two agree to float precision; ``weights="paper"`` is Algorithm 1 literally: ``cos(latitude)
* max(0, n . centre)``. ``weights="moments"`` (needs a frame of at least ``sub x in_size``) goes
beyond the paper: per input texel the GPU first sums the moments ``(L, 1) w dOmega`` of the
full-resolution pixels, which makes the cosine sum over every texel wholly above the horizon of
``n`` the full-resolution one exactly; the texels the horizon cuts take their ``sub x sub``
radiances from a finer area average. Only geometry (texel directions, solid angles) is
precomputed, never lighting.
"""

from __future__ import annotations

import moderngl
import numpy as np

from probeless.errors import ProbelessError
from probeless.gl.context import current_context
from probeless.gl.textures import upload_texture
from probeless.pano.equirect import check_equirect, pixel_directions, pixel_to_direction
from probeless.pano.gpu_pass import GpuPasses

WEIGHTS = ("subtexel", "paper", "moments")
NORMALIZE = ("weights", "pi")


def _size(size, what: str) -> tuple[int, int]:
    w, h = (int(s) for s in size)
    if h < 1 or w != 2 * h:
        raise ProbelessError(f"GpuDiffuse: {what} must be (2H, H), got {tuple(size)}")
    return w, h


def texel_geometry(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Per texel of a (W, H) equirect: (moment (H, W, 4): exact ``integral of w dOmega`` and the sine
    of a bound on the texel's angular radius; centre (H, W, 4): centre direction and cos(latitude))."""
    t = np.linspace(0.0, np.pi, height + 1)
    dt, dp = np.pi / height, 2.0 * np.pi / width
    s2 = np.diff(t / 2 - np.sin(2 * t) / 4)  # integral of sin^2 t over each row
    sc = np.diff(np.sin(t) ** 2 / 2)  # integral of sin t cos t over each row
    # the column centres' horizontal directions (cos p, -sin p): the equirect convention's, whatever it is
    horizon = pixel_to_direction(np.arange(width) + 0.5, np.full(width, height / 2.0), width, height)[:, :2]
    half = 2.0 * np.sin(dp / 2)  # integral of cos over a column is this * cos(centre), same for sin
    mom = np.empty((height, width, 4))
    mom[..., :2] = s2[:, None, None] * half * horizon[None]
    mom[..., 2] = sc[:, None] * dp
    mom[..., 3] = np.sin(min(dt / 2 + dp / 2, np.pi / 2))  # radius <= half the row + half the column
    dirs = pixel_directions(width, height)
    centre = np.concatenate([dirs, np.hypot(dirs[..., :1], dirs[..., 1:2])], axis=2)
    return mom.astype(np.float32), centre.astype(np.float32)


class GpuDiffuse(GpuPasses):
    """Diffuse radiance maps of equirect HDR frames on the GPU (see the module docstring)."""

    def __init__(self, ctx: moderngl.Context | None = None, out_size: tuple[int, int] = (32, 16),
                 in_size: tuple[int, int] = (128, 64), *, weights: str = "subtexel", sub: int = 4,
                 normalize: str = "weights"):
        if weights not in WEIGHTS or normalize not in NORMALIZE or not 1 <= int(sub) <= 16:
            raise ProbelessError(f"GpuDiffuse: weights must be one of {WEIGHTS} (got {weights!r}), normalize one "
                                 f"of {NORMALIZE} (got {normalize!r}), sub in 1..16 (got {sub})")
        self.out_size, self.in_size = _size(out_size, "out_size"), _size(in_size, "in_size")
        super().__init__(ctx)
        self.weights, self.sub = weights, int(sub)
        self.defines = dict(SUB=int(sub), PAPER_WEIGHTS=int(weights == "paper"), MOMENTS=int(weights == "moments"),
                            BY_WEIGHTS=int(normalize == "weights"))
        mom, centre = texel_geometry(*self.in_size)
        self.moment, self.centre = upload_texture(self.ctx, mom), upload_texture(self.ctx, centre)
        self.normals = upload_texture(self.ctx, pixel_directions(*self.out_size).astype(np.float32))
        self.program("diffuse", **self.defines)  # compile now: fail early, not on the first frame
        self._frame: moderngl.Texture | None = None

    def _upload(self, hdr: np.ndarray) -> moderngl.Texture:
        img = check_equirect(hdr, "GpuDiffuse")
        if img.dtype.kind != "f" or img.shape[2] != 3:
            raise ProbelessError(f"GpuDiffuse: expected a float RGB image, got {img.dtype} with {img.shape[2]} "
                                 f"channel(s)")
        self._frame = upload_texture(self.ctx, img, self._frame)
        return self._frame

    def _reduced(self, frame: moderngl.Texture, size: tuple[int, int]) -> moderngl.Texture:
        return frame if frame.size == size else self.area_downsample(frame, size).color_attachments[0]

    def _inputs(self, frame: moderngl.Texture) -> dict[str, moderngl.Texture]:
        if self.weights != "moments":
            return {"env": self._reduced(frame, self.in_size)}
        fine_size = (self.in_size[0] * self.sub, self.in_size[1] * self.sub)
        if frame.size[0] < fine_size[0]:
            raise ProbelessError(f"GpuDiffuse: weights='moments' needs a frame of at least {fine_size[0]}x"
                                 f"{fine_size[1]} (sub x in_size), got {frame.size[0]}x{frame.size[1]}")
        scale = (frame.size[0] / self.in_size[0], frame.size[1] / self.in_size[1])
        mom = self.draw("moments", self.in_size, {"src": frame}, attachments=3, scale=scale)
        mx, my, mz = mom.color_attachments
        return {"mx": mx, "my": my, "mz": mz, "fine": self._reduced(frame, fine_size)}

    @current_context
    def apply(self, hdr: np.ndarray) -> np.ndarray:
        """(H_out, W_out, 3) float32 diffuse map of the (H, 2H, 3) float16/float32 equirect ``hdr``."""
        textures = self._inputs(self._upload(hdr))
        textures.update(moment=self.moment, centre=self.centre, normals=self.normals)
        return self.read(self.draw("diffuse", self.out_size, textures, self.defines))

    @current_context
    def release(self) -> None:
        """Free the GL objects (the context too if this object created it)."""
        for tex in (self._frame, self.moment, self.centre, self.normals):
            if tex is not None:
                tex.release()
        self._frame = None
        super().release()
