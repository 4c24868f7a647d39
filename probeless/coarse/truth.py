"""Ground truth for the coarse model on synthetic scenes: the true colour of every atlas texel.

Each surface of the prism is rendered by the scene renderer through an orthographic camera 2 cm
inside the room, looking at the surface along its normal, with one pixel per texel -
the room's own radiance there (windows and ceiling panels included), then put through the
fisheye's exposure, clipping and sRGB encoding like the camera: camera LDR units 0..1.
"""

from __future__ import annotations

import numpy as np

from probeless.coarse.atlas import AtlasLayout, AtlasSurface
from probeless.color import linear_to_srgb

# camera distance from the surface: surface-mounted windows (2 mm) and ceiling panels (1 cm) count as the surface
STANDOFF_M = 0.02


def ortho_clip_from_world(layout: AtlasLayout, s: AtlasSurface, far: float) -> tuple[np.ndarray, np.ndarray]:
    """(clip_from_world (4, 4), eye (3,)) of an orthographic view of ``s`` filling its atlas rectangle."""
    d = layout.texels_per_m
    _, _, w, h = s.rect
    eye = s.origin + s.normal * STANDOFF_M
    ax, ay = 2.0 * d / w, 2.0 * d / h
    clip = np.zeros((4, 4))
    clip[0, :3], clip[0, 3] = ax * s.u_axis, -ax * (s.u_axis @ s.origin) - 1.0
    clip[1, :3], clip[1, 3] = ay * s.v_axis, -ay * (s.v_axis @ s.origin) - 1.0
    # depth = distance in front of the camera along -normal, mapped from [0, far] to [-1, 1]
    clip[2, :3], clip[2, 3] = -2.0 / far * s.normal, 2.0 / far * (s.normal @ eye) - 1.0
    clip[3, 3] = 1.0
    return clip, eye


def true_atlas(renderer, layout: AtlasLayout, light_scale: np.ndarray, exposure: float) -> np.ndarray:
    """(H, W, 3) float32 camera LDR colour of every core texel (0 elsewhere) with the lights at ``light_scale``."""
    out = np.zeros((layout.height, layout.width, 3), np.float32)
    lo, hi = layout.floorplan.min(axis=0), layout.floorplan.max(axis=0)
    far = float(np.linalg.norm(hi - lo)) + layout.ceiling_height + 1.0
    for s in layout.surfaces:
        x0, y0, w, h = s.rect
        clip, eye = ortho_clip_from_world(layout, s, far)
        radiance = renderer.render_clip(clip, eye, w, h, light_scale)
        out[y0:y0 + h, x0:x0 + w] = linear_to_srgb(radiance * exposure)
    return out
