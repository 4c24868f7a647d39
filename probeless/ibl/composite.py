"""Compositing rendered virtual objects into the RGB camera image (differential rendering).

The camera image is sRGB-encoded LDR. Object pixels are replaced by the render (linear camera
units, clipped and sRGB-encoded like the camera would); real pixels in a contact shadow are decoded
to linear, multiplied by the shadow ratio and re-encoded; every other pixel is left untouched.
"""

from __future__ import annotations

import numpy as np

from probeless.color import from_srgb8
from probeless.errors import SchemaError
from probeless.ibl.render import RenderResult
from probeless.scene.rig import expose


def encode_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear camera values to uint8 sRGB (clipped to 0..1), the way the camera encodes: through the
    synthetic rig's table (:func:`probeless.scene.rig.expose`), which may differ from
    :func:`probeless.color.to_srgb8` by one code."""
    return expose(np.asarray(linear, np.float32), 1.0)


def composite(rgb: np.ndarray, render: RenderResult, real_depth: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 3) uint8: ``rgb`` with the objects drawn over it and their contact shadows applied.

    ``real_depth`` (H, W) metres along the optical axis (0 = unknown), registered to ``rgb``, hides
    object pixels behind real surfaces.
    """
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise SchemaError(f"composite: rgb must be (H, W, 3) uint8, got {rgb.shape} {rgb.dtype}")
    if rgb.shape[:2] != render.mask.shape:
        raise SchemaError(f"composite: image {rgb.shape[:2]} and render {render.mask.shape} differ in size")
    mask = render.mask
    if real_depth is not None:
        if real_depth.shape != mask.shape:
            raise SchemaError(f"composite: depth {real_depth.shape} and render {mask.shape} differ in size")
        mask = mask & ~((real_depth > 0) & (real_depth < render.depth))
    out = rgb.copy()
    shaded = np.any(render.shadow < 1.0, axis=2) & ~render.mask
    if shaded.any():
        out[shaded] = encode_srgb8(from_srgb8(rgb[shaded]) * render.shadow[shaded])
    if mask.any():
        out[mask] = encode_srgb8(render.color[mask])
    return out


def render_camera(info, who: str) -> bool:
    """Check that ``info`` (a CameraInfo) is a pinhole the compositors can render through; True when it has
    distortion coefficients, which the renders ignore. :class:`SchemaError` names ``who`` otherwise."""
    if info.model != "pinhole":
        raise SchemaError(f"{who}: input 'camera_info': model must be pinhole, got {info.model!r}")
    return bool(np.any(info.D != 0))
