"""The dense model drawn over an existing environment map ("baseline + dense", paper §5.3).

Renders the dense points alone (over a black room) and again in white to know which texels they
cover, then replaces those texels of the given faces - the same "dense on top, no depth test
against the room" rule as :class:`~probeless.envmap.cubemap.EnvmapRenderer`.
"""

from __future__ import annotations

import numpy as np

from probeless.coarse.atlas import layout_atlas
from probeless.envmap.cubemap import EnvmapRenderer


class DenseOverlay:
    """Dense points over cubemaps of a room with ``floorplan`` x ``ceiling_height``."""

    def __init__(self, floorplan: np.ndarray, ceiling_height: float, *, ctx=None):
        layout = layout_atlas(floorplan, ceiling_height, 4.0)  # a tiny black room: only the dense pass matters
        self.renderer = EnvmapRenderer(layout, ctx=ctx)
        self.renderer.set_atlas(np.zeros((layout.height, layout.width, 3), np.uint8))
        self.points: tuple[np.ndarray, np.ndarray] | None = None

    def set_points(self, points: np.ndarray, colors: np.ndarray) -> None:
        """The dense model: (N, 3) world points, (N, 3) uint8 colours (camera LDR)."""
        self.points = (np.asarray(points, np.float32), np.asarray(colors))

    def over(self, faces: np.ndarray, position: np.ndarray, delta=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """(faces with the dense model on top, (6, S, S) bool texels it covers)."""
        size = faces.shape[1]
        if self.points is None or not len(self.points[0]):
            return faces, np.zeros(faces.shape[:3], bool)
        pts, cols = self.points
        self.renderer.set_dense(pts, np.full((len(pts), 3), 255, np.uint8))
        covered = self.renderer.render(position, size).max(axis=3) > 0.5
        self.renderer.set_dense(pts, cols)
        dense = self.renderer.render(position, size, delta=delta)
        return np.where(covered[..., None], dense, faces), covered

    def release(self) -> None:
        self.renderer.release()
