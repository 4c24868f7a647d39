"""Completing never-observed texels of the coarse model's atlas (paper §4.5).

Each surface (wall i, floor, ceiling) is inpainted on its own with OpenCV's fast-marching method
(Telea) so that colours never cross from one surface to another. Only texels that belong to the
surface (``texmap.valid``) and were never observed are filled; observed texels are returned
untouched. Inpainting runs at a reduced resolution (``scale``): observed colours are averaged
down (each low-resolution pixel that covers any observed texel counts as known), the holes are
filled there and the result is upsampled bilinearly.

A surface without any observed texel stays unfilled, except the floor, which a fisheye looking up
may not see for a long time: its boundary texels are seeded with the colour of the lowest observed
texel of the nearest wall, in the column above them (columns without observations take the colour
of the nearest observed column), and the rest of the floor is inpainted from that seed ring (at
``FLOOR_FROM_WALLS_SCALE`` times the usual scale). Once any floor texel is observed, the floor is
inpainted from its own observations only.
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.coarse.atlas import AtlasLayout, AtlasSurface
from probeless.coarse.texels import TexelMap
from probeless.errors import SchemaError

_RING = 2  # texels around a rectangle that texel_map may give to its surface
# OpenCV's Telea adds a term of magnitude ~1 intensity unit per filled pixel (harmless for 8-bit
# images, ruinous for 0..1 floats: opencv/opencv#25404); working in units of 1/65536 makes it ~3e-5.
_TELEA_UNITS = 65536.0
# A floor filled from the wall seeds alone is one big hole: a coarser pass keeps that cheap
# (it is only a plausible first texture, low in detail anyway).
FLOOR_FROM_WALLS_SCALE = 0.5


def _crop(layout: AtlasLayout, s: AtlasSurface) -> tuple[slice, slice]:
    """Rows and columns of ``s``'s rectangle grown by the padding ring, clipped to the atlas."""
    x0, y0, w, h = s.rect
    return (slice(max(0, y0 - _RING), min(layout.height, y0 + h + _RING)),
            slice(max(0, x0 - _RING), min(layout.width, x0 + w + _RING)))


def _telea(img: np.ndarray, fill: np.ndarray, radius: float) -> np.ndarray:
    """``img`` (h, w, 3) float32 with the ``fill`` texels inpainted (cv2 takes float images one channel at a time)."""
    mask = fill.astype(np.uint8)
    big = img * np.float32(_TELEA_UNITS)
    out = np.stack([cv2.inpaint(np.ascontiguousarray(big[..., c]), mask, radius, cv2.INPAINT_TELEA)
                    for c in range(3)], axis=-1)
    return out * np.float32(1.0 / _TELEA_UNITS)


def fill_surface(img: np.ndarray, known: np.ndarray, scale: float, radius: float) -> np.ndarray:
    """(h, w, 3) float32: ``img`` completed from its ``known`` texels, inpainted at ``scale`` and upsampled."""
    seen = cv2.copyTo(img, known.view(np.uint8))  # 0 where unknown (much faster than np.where)
    if scale >= 1.0:
        return _telea(seen, ~known, radius)
    h, w = known.shape
    small = (max(1, round(w * scale)), max(1, round(h * scale)))
    den = cv2.resize(known.astype(np.float32), small, interpolation=cv2.INTER_AREA)
    num = cv2.resize(seen, small, interpolation=cv2.INTER_AREA)
    small_known = den > 1e-6
    colour = np.where(small_known[..., None], num / np.maximum(den, 1e-6)[..., None], 0).astype(np.float32)
    filled = _telea(colour, ~small_known, radius)
    return cv2.resize(filled, (w, h), interpolation=cv2.INTER_LINEAR).reshape(h, w, 3)


def _wall_bottom_colours(atlas: np.ndarray, observed: np.ndarray, texmap: TexelMap, s: AtlasSurface
                         ) -> np.ndarray | None:
    """(w, 3) per wall column: the lowest observed texel's colour (nearest observed column where none);
    None if unseen."""
    x0, y0, w, h = s.rect
    seen = observed[y0:y0 + h, x0:x0 + w] & texmap.core[y0:y0 + h, x0:x0 + w]
    cols = np.flatnonzero(seen.any(axis=0))
    if len(cols) == 0:
        return None
    lowest = h - 1 - np.argmax(seen[::-1, cols], axis=0)  # rows run down the wall
    colours = atlas[y0 + lowest, x0 + cols]
    nearest = cols[np.abs(np.arange(w)[:, None] - cols[None, :]).argmin(axis=1)]
    return colours[np.searchsorted(cols, nearest)]


def floor_seeds(atlas: np.ndarray, observed: np.ndarray, layout: AtlasLayout, texmap: TexelMap
                ) -> tuple[np.ndarray, np.ndarray]:
    """(known (h, w) bool, colour (h, w, 3) float32) over the floor's crop: its edge texels coloured from the walls.

    An edge texel (a floor texel within one texel of the floorplan's outline) takes the bottom colour
    of the nearest wall at the same position along that wall; walls never observed seed nothing.
    """
    k = next(i for i, s in enumerate(layout.surfaces) if s.kind == "floor")
    rows, cols = _crop(layout, layout.surfaces[k])
    floor = texmap.surface[rows, cols] == k
    inner = cv2.erode((floor & texmap.core[rows, cols]).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    edge = floor & ~inner
    xy = texmap.position[rows, cols][edge][:, :2].astype(np.float64)
    best = np.full(len(xy), np.inf)
    colour = np.zeros((len(xy), 3), np.float32)
    poly = layout.floorplan
    for i, wall in enumerate(layout.walls):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        t = np.clip((xy - a) @ (b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        dist = np.linalg.norm(xy - (a + t[:, None] * (b - a)), axis=1)
        closer = dist < best
        best[closer] = dist[closer]
        bottom = _wall_bottom_colours(atlas, observed, texmap, wall)
        if bottom is None:
            colour[closer] = np.nan  # nearest so far is a wall never seen
            continue
        col = np.clip((t * wall.size_m[0] * layout.texels_per_m).astype(int), 0, wall.rect[2] - 1)
        colour[closer] = bottom[col[closer]]
    seeded = np.isfinite(colour).all(axis=1)
    known = np.zeros(floor.shape, bool)
    img = np.zeros((*floor.shape, 3), np.float32)
    idx = np.argwhere(edge)[seeded]
    known[idx[:, 0], idx[:, 1]] = True
    img[idx[:, 0], idx[:, 1]] = colour[seeded]
    return known, img


def inpaint_atlas(atlas: np.ndarray, observed: np.ndarray, layout: AtlasLayout, texmap: TexelMap, *,
                  scale: float = 0.25, radius: float = 3) -> tuple[np.ndarray, np.ndarray]:
    """(filled (H, W, 3) float32, inpainted (H, W) bool): never-observed surface texels completed per surface.

    ``radius`` is Telea's neighbourhood in pixels of the reduced-resolution image. Texels not
    inpainted (observed, gaps, surfaces never seen) keep the input's values bit for bit.
    """
    H, W = layout.height, layout.width
    if atlas.shape != (H, W, 3) or atlas.dtype != np.float32:
        raise SchemaError(f"inpaint_atlas: atlas must be ({H}, {W}, 3) float32, got {atlas.shape} {atlas.dtype}")
    if observed.shape != (H, W) or observed.dtype != bool:
        raise SchemaError(f"inpaint_atlas: observed must be ({H}, {W}) bool, got {observed.shape} {observed.dtype}")
    if not (0 < scale <= 1) or not radius > 0:
        raise SchemaError(f"inpaint_atlas: need 0 < scale <= 1 and radius > 0, got scale={scale}, radius={radius}")
    filled, inpainted = atlas.copy(), np.zeros((H, W), bool)
    for k, s in enumerate(layout.surfaces):
        rows, cols = _crop(layout, s)
        mine = texmap.surface[rows, cols] == k
        known = observed[rows, cols] & mine
        missing = mine & ~known
        if not missing.any():
            continue
        img, at = atlas[rows, cols], scale
        if not known.any():
            if s.kind != "floor":
                continue
            known, img = floor_seeds(atlas, observed, layout, texmap)
            if not known.any():
                continue
            at = scale * FLOOR_FROM_WALLS_SCALE
        out = fill_surface(img, known, at, radius)
        cv2.copyTo(out, missing.view(np.uint8), filled[rows, cols])  # writes into the view
        inpainted[rows, cols] |= missing
    return filled, inpainted


class IncrementalInpainter:
    """Re-runs :func:`inpaint_atlas` only once the observed mask has changed in ``min_new_texels`` texels."""

    def __init__(self, layout: AtlasLayout, texmap: TexelMap, *, min_new_texels: int = 1024,
                 scale: float = 0.25, radius: float = 3):
        if min_new_texels < 1:
            raise SchemaError(f"IncrementalInpainter: min_new_texels must be >= 1, got {min_new_texels}")
        self.layout, self.texmap = layout, texmap
        self.min_new_texels, self.scale, self.radius = int(min_new_texels), scale, radius
        self.runs = 0
        self._last: np.ndarray | None = None  # observed mask at the last run

    def changed(self, observed: np.ndarray) -> bool:
        """Whether a run is due: none yet, or ``min_new_texels`` texels of ``observed`` differ from the last run's."""
        return self._last is None or np.count_nonzero(observed != self._last) >= self.min_new_texels

    def run(self, atlas: np.ndarray, observed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`inpaint_atlas` now, remembering ``observed`` as the last run's mask."""
        result = inpaint_atlas(atlas, observed, self.layout, self.texmap, scale=self.scale, radius=self.radius)
        self._last = observed.copy()
        self.runs += 1
        return result

    def update(self, atlas: np.ndarray, observed: np.ndarray, *, force: bool = False
               ) -> tuple[np.ndarray, np.ndarray] | None:
        """:func:`run`'s result when due (see :meth:`changed`) or ``force``d, else None."""
        return self.run(atlas, observed) if force or self.changed(observed) else None
