"""Paper 003: the coarse texture starts neutral grey (sRGB code 128), not black; the first frame overwrites
what it sees and the rest stays grey (plus Δ), marked never observed."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.cameras.omnidir import OmnidirModel
from probeless.coarse.atlas import fit_atlas
from probeless.coarse.gpu import AtlasTexturer
from probeless.coarse.texels import texel_map

pytestmark = [pytest.mark.gl]


def test_fresh_atlas_is_neutral_grey_and_unobserved():
    layout = fit_atlas(np.array([[0.0, 0], [4, 0], [4, 3], [0, 3]]), 2.5, 128)
    texmap = texel_map(layout)
    tex = AtlasTexturer(layout, texmap, fov_deg=180.0)
    rgb, seen = tex.read_atlas()
    np.testing.assert_array_equal(rgb, np.float32(128 / 255))
    assert np.all(seen == -1.0)
    packed = tex.read_packed()
    assert np.all(packed[..., :3] == 128) and not packed[..., 3].any()
    # a black frame looking at the floor: what it sees turns black and observed, the rest stays grey
    model = OmnidirModel(64, 64, np.array([[20.0, 0, 31.5], [0, 20.0, 31.5], [0, 0, 1]]), 1.0)
    down = np.eye(4)
    down[:3, :3] = np.diag([1.0, -1.0, -1.0])  # camera z looks down (-world z)
    down[:3, 3] = (2.0, 1.5, 1.5)
    tex.update(np.zeros((64, 64, 3), np.uint8), model, down)
    rgb, seen = tex.read_atlas()
    now = seen >= 0
    assert now.sum() > 100 and np.all(rgb[now] == 0)
    np.testing.assert_array_equal(rgb[~now], np.float32(128 / 255))
    tex.release()
