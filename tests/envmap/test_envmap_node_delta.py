"""Δ reaches every dense point by when it was last fused (paper 003 §4.5), through the cubemap node."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.coarse.model import CoarseConfig, make_layout
from probeless.envmap.delta_history import DeltaHistory
from probeless.geom.cube import texel_from_direction
from probeless.messages.geometry import Floorplan
from probeless.messages.header import Header
from probeless.messages.lighting import BrightnessDelta
from probeless.messages.mesh import PointCloud
from probeless.messages.sensor import Image
from probeless.nodes.envmap.cubemap import CubemapRenderer
from probeless.runtime.testing import run_node

S = 1_000_000_000
FLOOR = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], np.float64)
CENTRE = np.array([2.0, 2.0, 1.2])


def test_history_sums_deltas_after_each_stamp_whatever_their_arrival_order():
    h = DeltaHistory()
    for stamp, d in ((3, [0.1, 0, 0]), (1, [0, 0.2, 0]), (2, [0, 0, 0.3]), (3, [0.05, 0, 0])):
        h.add(stamp, d)
    np.testing.assert_allclose(h.total(), [0.15, 0.2, 0.3])
    # what a colour fused at 0, 1, 2, 3, 9 still lacks: the Δ stamped strictly after it
    np.testing.assert_allclose(h.since([0, 1, 2, 3, 9]),
                               [[0.15, 0.2, 0.3], [0.15, 0, 0.3], [0.15, 0, 0], [0, 0, 0], [0, 0, 0]], atol=1e-7)
    small = DeltaHistory(max_entries=2)
    for k in range(5):
        small.add(k, [1.0, 0, 0])
    assert len(small.stamps) == 2 and small.total()[0] == 5.0 and small.since([3])[0, 0] == 1.0
    with pytest.raises(ValueError, match="non-finite"):
        h.add(4, [np.nan, 0, 0])


def _texel(face_size, point):
    f, r, c = texel_from_direction((np.asarray(point) - CENTRE)[None], face_size)
    return int(f[0]), int(np.rint(r[0])), int(np.rint(c[0]))


@pytest.mark.gl
def test_points_fused_before_a_light_switch_get_it_when_a_new_model_arrives():
    """A new dense model arrives after the switch: the wall seen before it (old colours) gets the switch's Δ, the
    wall fused after it keeps its colours. Before the fix both kept their colours (Δ reset on every new model)."""
    layout = make_layout(FLOOR, 2.5, CoarseConfig(256, 0.0))
    atlas = np.full((layout.height, layout.width, 4), 128, np.uint8)
    a = np.array([3.9, 2.0, 1.2], np.float32)    # +X wall, fused at 1 s (before the switch)
    b = np.array([0.1, 2.0, 1.2], np.float32)    # -X wall, fused at 5 s (after it)
    grid = np.stack(np.meshgrid(np.linspace(-0.3, 0.3, 13), np.linspace(-0.3, 0.3, 13)), -1).reshape(-1, 2)
    pts = np.concatenate([np.c_[np.full(len(grid), a[0]), a[1] + grid[:, 0], a[2] + grid[:, 1]],
                          np.c_[np.full(len(grid), b[0]), b[1] + grid[:, 0], b[2] + grid[:, 1]]]).astype(np.float32)
    colors = np.full((len(pts), 3), 100, np.uint8)
    stamps = np.r_[np.full(len(grid), 1 * S), np.full(len(grid), 5 * S)].astype(np.int64)
    switch = BrightnessDelta(Header(3 * S, "fisheye"), np.float32([0.2, 0.2, 0.2]), 500, True)
    later = BrightnessDelta(Header(7 * S, "fisheye"), np.float32([0.0, 0.1, 0.0]), 500, True)
    msgs = [("floorplan", Floorplan(Header(0, "world"), FLOOR, 2.5)),
            ("delta", switch),
            ("points", PointCloud(Header(6 * S, "world"), pts, colors, stamps_ns=stamps)),
            ("delta", later),
            ("atlas", Image(Header(8 * S, "world"), atlas, "rgba8"))]
    ctx = run_node(CubemapRenderer, msgs, dict(atlas_size=256, object_ids=["o"], object_positions=[CENTRE.tolist()],
                                               face_size=32, mip_levels=1, splat_m=0.1, observed=False))
    (cube,) = ctx.outputs("envmap/o")
    got_a = cube.faces[_texel(32, a)].astype(float)
    got_b = cube.faces[_texel(32, b)].astype(float)
    # A: 100 + switch (51) + later (0, 25.5, 0); B: 100 + later only (the switch is in its colours already)
    np.testing.assert_allclose(got_a, [151, 176.5, 151], atol=1.0)
    np.testing.assert_allclose(got_b, [100, 125.5, 100], atol=1.0)
    assert ctx.outputs("envmaps")[0] is cube  # every object on one topic as well
