"""Both envmap nodes write the cube net of each object's last map (the paper's Figure 9) when asked."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from probeless.coarse.atlas import fit_atlas
from probeless.messages.geometry import Floorplan
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.envmap.cubemap import CubemapRenderer
from probeless.runtime.testing import run_node

pytestmark = [pytest.mark.gl, pytest.mark.graph]

SQUARE = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])


def test_cubemap_renderer_writes_the_net(tmp_path):
    layout = fit_atlas(SQUARE, 2.5, 64)
    atlas = np.zeros((64, 64, 4), np.uint8)
    ceiling = layout.surface("ceiling").rect
    atlas[..., :3] = 40
    x0, y0, w, h = ceiling
    atlas[max(0, y0 - 2):y0 + h + 2, max(0, x0 - 2):x0 + w + 2, :3] = (250, 20, 20)  # a red ceiling
    msgs = [("floorplan", Floorplan(Header(0, "world"), SQUARE, 2.5)),
            ("atlas", Image(Header(1, "world"), atlas, "rgba8"))]
    run_node(CubemapRenderer, msgs, {"object_ids": ["ball"], "object_positions": [[2.0, 2.0, 1.0]],
                                     "face_size": 32, "mip_levels": 1, "net_dir": str(tmp_path)})
    net = cv2.imread(str(tmp_path / "cubemap_net_ball.png"))[..., ::-1]
    assert net.shape == (96, 128, 3)  # 3 x 4 tiles of 32
    up, side = net[:32, 32:64], net[32:64, :]
    np.testing.assert_allclose(up.reshape(-1, 3).mean(axis=0), (250, 20, 20), atol=3)  # +Z tile: the ceiling
    assert abs(side[16:].reshape(-1, 3).mean(axis=0) - 40).max() < 3  # below the horizon: walls and floor


def test_baseline_plus_dense_draws_points_on_top():
    from probeless.envmap.overlay import DenseOverlay
    from probeless.geom.cube import texel_from_direction

    overlay = DenseOverlay(SQUARE, 2.5)
    # a green patch of points 1 m in +X of the object: it must cover the +X face centre, nothing behind it
    yy, zz = np.meshgrid(np.linspace(-0.2, 0.2, 40), np.linspace(-0.2, 0.2, 40))
    pts = np.stack([np.full(yy.size, 3.0), 2.0 + yy.ravel(), 1.0 + zz.ravel()], axis=1)
    overlay.set_points(pts, np.tile([[0, 255, 0]], (len(pts), 1)).astype(np.uint8))
    base = np.full((6, 32, 32, 3), 0.5, np.float32)
    out, covered = overlay.over(base, np.array([2.0, 2.0, 1.0]))
    face, row, col = texel_from_direction(np.array([1.0, 0.0, 0.0]), 32)
    r, c = int(round(float(row))), int(round(float(col)))
    assert int(face) == 0 and covered[0, r, c]
    np.testing.assert_allclose(out[0, r, c], (0, 1, 0), atol=0.02)
    assert not covered[1].any() and np.all(out[1] == 0.5)  # -X untouched
    overlay.release()
