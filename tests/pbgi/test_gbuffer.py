"""The objects' G-buffer (probeless.pbgi.gbuffer): spatially varying materials from texture maps, read through the
mesh UVs, against probeless.pbgi.textures.sample_map (the OBJ convention: v up the image)."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.gl.context import create_context
from probeless.ibl.mesh_io import PlacedMesh
from probeless.pbgi.gbuffer import GBufferRenderer
from probeless.pbgi.materials import Brdf
from probeless.pbgi.textures import sample_map

pytestmark = pytest.mark.gl


def test_maps_vary_the_material_across_the_surface_as_the_uvs_say():
    quad = PlacedMesh(np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]), np.array([[0, 1, 2], [0, 2, 3]]),
                      np.tile([0, 0, 1.0], (4, 1)), np.zeros(3), uvs=np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]]))
    base = np.array([[[1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 1, 1]]], np.float32)  # 2 x 2 texels, row 0 on top
    rough = np.array([[0.1, 0.4], [0.7, 0.9]], np.float32)
    metal = np.array([[0.0, 1.0], [0.5, 0.25]], np.float32)
    brdf = Brdf("disney", (0.5, 0.5, 0.5), 0.5, 0.0, base_color_map=base, roughness_map=rough, metalness_map=metal)
    ctx = create_context()
    try:
        g = GBufferRenderer(ctx)
        g.set_objects([(quad, brdf)])
        size = 32
        K = np.array([[size / 2, 0, size / 2 - 0.5], [0, size / 2, size / 2 - 0.5], [0, 0, 1.0]])
        pose = np.eye(4)
        pose[:3, :3] = np.diag([1.0, -1, -1])  # above the quad looking down: image right = +x, image down = -y
        pose[:3, 3] = [0, 0, 2.0]
        gb = g.render(K, pose, size, size)
        g.release()
    finally:
        ctx.release()
    assert gb.mask[8:24, 8:24].all() and (gb.model[gb.mask] == 2).all()
    for row, col in ((10, 10), (10, 21), (21, 10), (21, 21)):  # the centres of the four texels' areas
        x, y = gb.position[row, col, :2]
        uv = np.array([[(x + 1) / 2, (y + 1) / 2]])
        np.testing.assert_allclose(gb.base_color[row, col], sample_map(base, uv)[0], atol=0.03)
        np.testing.assert_allclose(gb.roughness[row, col], sample_map(rough, uv)[0], atol=0.03)
        np.testing.assert_allclose(gb.metalness[row, col], sample_map(metal, uv)[0], atol=0.03)
    assert len({tuple(np.round(gb.base_color[r, c], 1)) for r, c in ((10, 10), (10, 21), (21, 10), (21, 21))}) == 4
