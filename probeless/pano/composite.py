"""Compositing IBL-lit objects over the perspective view of an LDR 360° frame (paper 002, Algorithm 1).

Background pixels are the LDR video frame as it is stored (display values, sRGB uint8), sampled by
the view. Object pixels are linear renders in the units of the HDR frame; they go back to the
display encoding by inverting the way the frame was expanded to HDR, after an ``exposure`` scale:

* ``direct`` (for the paper's operator, which expands the stored 0..1 values without linearising
  them): clip to 0..1 and write the value as it is;
* ``gamma``: for operators fed ``gamma_decode``-d values (``x ** 2.2``): clip, then ``x ** (1 / 2.2)``;
* ``srgb``: for frames linearised with the sRGB curve: clip, then the sRGB encoding.

So with exposure 1, an LDR value that the ITMO leaves unchanged comes back to the same code.
"""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np

from probeless.color import to_srgb8
from probeless.errors import ProbelessError
from probeless.pano.view import side_by_side, stereo_eye_poses

DISPLAY = ("direct", "gamma", "srgb")
# the encoding that undoes each ``itmo`` node operator's reading of the stored values
# (nodes/pano/lighting.py: paper and ldr take values / 255; landis, akyuz, banterle gamma-decode
# them first, with ``linearize`` on by default; none decodes sRGB)
DISPLAY_FOR_OPERATOR = {"paper": "direct", "ldr": "direct", "landis": "gamma", "akyuz": "gamma",
                        "banterle": "gamma", "none": "srgb"}


def encode_display(linear: np.ndarray, display: str = "direct", gamma: float = 2.2) -> np.ndarray:
    """uint8 display codes of linear values (any shape): clip to 0..1, encode per ``display``, round."""
    if display == "srgb":
        return to_srgb8(np.asarray(linear, np.float32))
    x = np.clip(np.asarray(linear, np.float32), 0.0, 1.0)
    if display == "gamma":
        x = x ** np.float32(1.0 / gamma)
    elif display != "direct":
        raise ProbelessError(f"encode_display: unknown display {display!r}; choices: {', '.join(DISPLAY)}")
    return np.rint(x * 255.0).astype(np.uint8)


def composite_view(background: np.ndarray, color: np.ndarray, mask: np.ndarray, exposure: float = 1.0,
                   display: str = "direct") -> np.ndarray:
    """(H, W, 3) uint8: ``background`` with the object pixels (``mask``) replaced by the encoded render."""
    if background.dtype != np.uint8 or background.shape[:2] != mask.shape or color.shape[:2] != mask.shape:
        raise ProbelessError(f"composite_view: background {background.shape} {background.dtype}, colour "
                             f"{color.shape} and mask {mask.shape} must be uint8 images of one size")
    out = background.copy()
    out[mask] = encode_display(color[mask] * np.float32(exposure), display)
    return out


def render_view(renderer, world_from_head: np.ndarray, fov_deg: float, width: int, height: int, *,
                stereo: bool = False, ipd_m: float = 0.064, exposure: float = 1.0, display: str = "direct",
                background=None, timed=None) -> np.ndarray:
    """One output frame of a :class:`~probeless.pano.render.PanoRenderer` whose environment and
    background are set: mono (height, width, 3) or stereo side by side (height, 2 width, 3).

    ``background(world_from_eye) -> uint8 view`` overrides the renderer's GPU background pass;
    ``timed(stage)`` is a context manager factory for stage timings (``render``, ``background``,
    ``composite``).
    """
    timed = timed or (lambda stage: nullcontext())
    with timed("background"):  # the panorama is at infinity: both eyes see the same background
        bg = renderer.background(fov_deg, world_from_head, width, height) if background is None \
            else background(world_from_head)
    views = []
    for eye in stereo_eye_poses(world_from_head, ipd_m) if stereo else (world_from_head,):
        with timed("render"):
            color, mask = renderer.render(fov_deg, eye, width, height)
        with timed("composite"):
            views.append(composite_view(bg, color, mask, exposure, display))
    return side_by_side(*views) if stereo else views[0]
