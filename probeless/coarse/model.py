"""The coarse room model as one object: layout, GPU atlas, occlusion and incremental inpainting.

:class:`CoarseModel` is what the ``coarse_texturer`` node, ``probeless coarse preview``, the
accuracy evaluation and ``probeless bench coarse`` drive, one fisheye frame at a time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from probeless.coarse.atlas import AtlasLayout, fit_atlas, layout_atlas
from probeless.coarse.gpu import AtlasTexturer
from probeless.coarse.inpaint import IncrementalInpainter
from probeless.coarse.texels import TexelMap, texel_map
from probeless.errors import GeometryError

INPAINTED_S = -2.0  # last_seen value of texels filled by inpainting (never observed directly)


@dataclass(frozen=True)
class CoarseConfig:
    """How the atlas is laid out and updated (the texturer node's params)."""

    atlas_size: int = 2048        # atlas is atlas_size x atlas_size when texels_per_m == 0 [texels]
    texels_per_m: float = 0.0     # uniform texel density; 0 = the densest that fits atlas_size [texels/m]
    fov_deg: float = 180.0        # texels further than fov/2 from the fisheye's axis are out of view [deg]
    inpaint: bool = True          # fill never-observed texels (Telea, per surface)
    inpaint_scale: float = 0.25   # resolution of the inpainting relative to the atlas [-]
    inpaint_min_new_texels: int = 2000  # re-inpaint once this many texels were newly observed [count]
    inpaint_every: int = 10       # ... and at least this many frames after the last run [frames]
    occlusion_offset_texels: float = 1.5  # wall texels are tested this far inside the room [texels]
    occlusion: bool = True        # False: ignore self-occlusion of non-convex rooms (an ablation)


def make_layout(floorplan: np.ndarray, ceiling_height: float, config: CoarseConfig) -> AtlasLayout:
    """The atlas layout both the texturer and the brightness estimator derive from the same params."""
    if config.texels_per_m > 0:
        return layout_atlas(floorplan, ceiling_height, config.texels_per_m)
    return fit_atlas(floorplan, ceiling_height, config.atlas_size)


class CoarseModel:
    """Texture the prism of ``floorplan`` x ``ceiling_height`` from fisheye frames (paper §4.3–4.5)."""

    def __init__(self, floorplan: np.ndarray, ceiling_height: float, config: CoarseConfig = CoarseConfig(), *,
                 ctx=None, layout: AtlasLayout | None = None, texmap: TexelMap | None = None):
        self.config = config
        self.layout = layout or make_layout(floorplan, ceiling_height, config)
        self.texmap = texmap or texel_map(self.layout)
        self.gpu = AtlasTexturer(self.layout, self.texmap, fov_deg=config.fov_deg, ctx=ctx,
                                 occlusion_offset_texels=config.occlusion_offset_texels,
                                 occlusion=config.occlusion)
        self.inpainter = IncrementalInpainter(self.layout, self.texmap, min_new_texels=config.inpaint_min_new_texels,
                                              scale=config.inpaint_scale) if config.inpaint else None
        self.frames = 0
        self._last_inpaint = -config.inpaint_every
        self.timings_ms: dict[str, list[float]] = {"occlusion": [], "texture": [], "inpaint": []}

    def _timed(self, stage: str, fn, *args):
        t0 = time.perf_counter()
        out = fn(*args)
        self.gpu.ctx.finish()
        self.timings_ms[stage].append((time.perf_counter() - t0) * 1e3)
        return out

    def step(self, image: np.ndarray, model, world_from_fisheye: np.ndarray, delta=(0.0, 0.0, 0.0),
             t_s: float = 0.0) -> bool:
        """Update the atlas with one fisheye frame; True when inpainting ran. GeometryError for a bad pose."""
        T = self.occlude(world_from_fisheye)
        self.update(image, model, T, delta, t_s)
        return self.inpaint_if_due()

    def occlude(self, world_from_fisheye: np.ndarray) -> np.ndarray:
        """The occlusion mask for the fisheye's floor position (paper §4.4); returns the checked pose."""
        T = np.asarray(world_from_fisheye, np.float64)
        if T.shape != (4, 4) or not np.isfinite(T).all():
            raise GeometryError(f"world_from_fisheye must be a finite 4x4 transform, got {T.shape}")
        self._timed("occlusion", self.gpu.occlusion, T[:2, 3])
        return T

    def update(self, image: np.ndarray, model, T: np.ndarray, delta=(0.0, 0.0, 0.0), t_s: float = 0.0) -> None:
        """Texture the visible texels from ``image``, Δ for the rest (paper §4.3, §4.6)."""
        self._timed("texture", self.gpu.update, image, model, T, delta, t_s)
        self.frames += 1

    def inpaint_if_due(self) -> bool:
        """Re-inpaint never-observed texels when enough new ones were observed (paper §4.5)."""
        return self._inpaint() if self.inpainter is not None else False

    def _inpaint(self) -> bool:
        if self.frames - self._last_inpaint < self.config.inpaint_every:
            return False
        observed = self.gpu.read_packed()[..., 3] > 0
        if not self.inpainter.changed(observed):
            return False
        self._last_inpaint = self.frames
        t0 = time.perf_counter()
        rgb, seen = self.gpu.read_atlas()
        filled, inpainted = self.inpainter.run(rgb, observed)
        seen = np.where(inpainted, INPAINTED_S, seen)
        self.gpu.write_atlas(np.where(inpainted[..., None], filled, rgb), seen)
        self.timings_ms["inpaint"].append((time.perf_counter() - t0) * 1e3)
        return True

    def atlas(self) -> tuple[np.ndarray, np.ndarray]:
        """(rgb (H, W, 3) float32 camera LDR units, last_seen_s (H, W): >= 0 seen, -1 never, -2 inpainted)."""
        return self.gpu.read_atlas()

    def observed_image(self) -> np.ndarray:
        """(H, W) uint8: 255 observed directly, 128 inpainted, 0 nothing yet (outside surfaces too)."""
        _, seen = self.gpu.read_atlas()
        return np.where(seen >= 0, 255, np.where(seen == INPAINTED_S, 128, 0)).astype(np.uint8)

    def release(self) -> None:
        self.gpu.release()
