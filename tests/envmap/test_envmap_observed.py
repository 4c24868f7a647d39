"""``EnvmapRenderer.observed_mask`` against the directions that hit an observed surface, and the dense points."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.coarse.atlas import fit_atlas
from probeless.envmap.cubemap import EnvmapRenderer
from probeless.errors import ProbelessError
from probeless.geom.cube import cube_directions

PAD = 2
EYE = np.array([2.0, 1.5, 1.25])


@pytest.fixture(scope="module")
def renderer():
    layout = fit_atlas(np.array([[0.0, 0], [4, 0], [4, 3], [0, 3]]), 2.5, 256)
    r = EnvmapRenderer(layout)
    yield r
    r.release()


def atlas_with_floor_observed(layout) -> np.ndarray:
    atlas = np.zeros((layout.height, layout.width, 4), np.uint8)
    atlas[..., :3] = 90
    floor = next(s for s in layout.surfaces if s.kind == "floor")
    x0, y0, w, h = floor.rect
    atlas[y0 - PAD:y0 + h + PAD, x0 - PAD:x0 + w + PAD, 3] = 255
    return atlas


@pytest.mark.gl
def test_observed_mask_is_the_rays_that_hit_the_observed_floor(renderer):
    renderer.set_atlas(atlas_with_floor_observed(renderer.layout))
    mask = renderer.observed_mask(EYE, 32)
    d = cube_directions(32)
    # a ray hits the floor where it leaves the box through z = 0: compare each axis' exit distance
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([4.0, 3.0, 2.5])
    with np.errstate(divide="ignore"):
        t = np.where(d > 0, (hi - EYE) / d, np.where(d < 0, (lo - EYE) / d, np.inf))
    hits_floor = (np.argmin(t, axis=-1) == 2) & (d[..., 2] < 0)
    wrong = mask != hits_floor
    assert hits_floor.sum() > 500 and wrong.sum() <= 0.02 * hits_floor.sum()  # texels on the floor's edges only
    # the map itself is untouched by the alpha: every texel has the atlas colour
    np.testing.assert_allclose(renderer.render(EYE, 32, dense=False), 90 / 255, atol=1e-6)


@pytest.mark.gl
def test_observed_mask_adds_dense_points_and_needs_alpha(renderer):
    atlas = np.zeros((renderer.layout.height, renderer.layout.width, 4), np.uint8)
    renderer.set_atlas(atlas)
    renderer.set_dense(np.array([[3.5, 1.5, 1.25]], np.float32), np.zeros((1, 3), np.uint8))  # black, still observed
    with_dense, without = renderer.observed_mask(EYE, 32, splat_m=0.3), renderer.observed_mask(EYE, 32, dense=False)
    assert not without.any()
    assert with_dense[0].sum() > 10 and with_dense.sum() == with_dense[0].sum()  # a disc on +X only
    assert with_dense[0, 15:17, 15:17].all()
    renderer.set_atlas(np.full_like(atlas[..., :3], 255))  # no alpha: no coarse texel counts, the dense still does
    np.testing.assert_array_equal(renderer.observed_mask(EYE, 32, splat_m=0.3), with_dense)
    renderer.clear_dense()


@pytest.mark.gl
def test_observed_mask_needs_an_atlas():
    layout = fit_atlas(np.array([[0.0, 0], [4, 0], [4, 3], [0, 3]]), 2.5, 64)
    r = EnvmapRenderer(layout)
    with pytest.raises(ProbelessError, match="no atlas"):
        r.observed_mask(EYE, 16)
    r.release()
