"""Inpainting never-observed atlas texels per surface (paper §4.5), against cv2.inpaint and analytic colours."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from probeless.coarse.atlas import layout_atlas
from probeless.coarse.inpaint import IncrementalInpainter, inpaint_atlas
from probeless.coarse.texels import texel_map
from probeless.errors import SchemaError

RECT = np.array([[0, 0], [4, 0], [4, 3], [0, 3]], float)
L_SHAPE = np.array([[0, 0], [6, 0], [6, 3], [3, 3], [3, 5], [0, 5]], float)


def _room(poly, d=20.0, padding=2):
    lay = layout_atlas(poly, 2.5, d, padding=padding)
    return lay, texel_map(lay)


def _bits(a):
    return np.ascontiguousarray(a).view(np.uint32)


def _blocks(shape, rng, p=0.5, block=6):
    """A random mask of ``block``-sized squares (so holes are regions, not single texels)."""
    small = rng.random((shape[0] // block + 1, shape[1] // block + 1)) < p
    return np.kron(small, np.ones((block, block), bool))[:shape[0], :shape[1]]


@pytest.mark.parametrize("poly", [RECT, L_SHAPE], ids=["rect", "l_shape"])
@pytest.mark.parametrize("scale", [0.25, 0.5, 1.0])
def test_observed_never_change_and_only_valid_texels_are_filled(poly, scale):
    lay, tm = _room(poly)
    rng = np.random.default_rng(1)
    atlas = rng.random((lay.height, lay.width, 3)).astype(np.float32)
    observed = _blocks(tm.valid.shape, rng)  # also marks some gap texels: they must be left alone too
    filled, inpainted = inpaint_atlas(atlas, observed, lay, tm, scale=scale)
    assert filled.dtype == np.float32 and filled.shape == atlas.shape
    np.testing.assert_array_equal(_bits(filled[observed]), _bits(atlas[observed]))
    np.testing.assert_array_equal(_bits(filled[~inpainted]), _bits(atlas[~inpainted]))
    # every surface has observed texels here, so exactly its never-observed valid texels are filled
    np.testing.assert_array_equal(inpainted, tm.valid & ~observed)
    assert np.isfinite(filled).all()


def _ramp(tm):
    x, y = tm.position[..., 0], tm.position[..., 1]
    return np.stack([x / 4, y / 3, 0.2 + 0.1 * x + 0.1 * y], -1).astype(np.float32)


def _cv2_telea(img, mask, units=65536.0):
    """cv2.inpaint (Telea, radius 3) of a float RGB image, channel by channel, in 1/``units`` steps.

    OpenCV's Telea adds up to ~2 intensity units per filled pixel (opencv/opencv#25404), so 0..1
    data must be scaled up first; see test_telea_needs_large_units.
    """
    return np.stack([cv2.inpaint(np.ascontiguousarray(img[..., c]) * np.float32(units), mask, 3, cv2.INPAINT_TELEA)
                     for c in range(3)], -1) / np.float32(units)


def test_telea_needs_large_units():
    """Raw cv2.inpaint on a constant 0..1 float image is off by ~1; inpaint_atlas fills it exactly."""
    lay, tm = _room(RECT)
    atlas = np.full((lay.height, lay.width, 3), 0.4, np.float32)
    rng = np.random.default_rng(4)
    observed = _blocks(tm.valid.shape, rng) & tm.valid
    raw = _cv2_telea(atlas, (~observed).astype(np.uint8), units=1.0)
    hole = tm.valid & ~observed
    assert np.abs(raw[hole] - 0.4).max() > 0.5
    filled, inpainted = inpaint_atlas(atlas, observed, lay, tm, scale=1.0)
    np.testing.assert_array_equal(inpainted, hole)
    np.testing.assert_allclose(filled[hole], 0.4, atol=1e-4)


def test_ramp_hole_matches_full_resolution_telea():
    lay, tm = _room(RECT, d=40.0)
    k = [s.kind for s in lay.surfaces].index("floor")
    x0, y0, w, h = lay.surfaces[k].rect
    atlas = _ramp(tm)
    xy = tm.position[..., :2]
    hole = (np.linalg.norm(xy - [2.0, 1.5], axis=2) < 0.4) & (tm.surface == k)
    observed = (tm.surface == k) & ~hole
    # reference: cv2.inpaint of the floor's own rectangle at full resolution
    crop, mask = atlas[y0:y0 + h, x0:x0 + w], hole[y0:y0 + h, x0:x0 + w].astype(np.uint8)
    ref = _cv2_telea(crop, mask)[mask > 0]
    truth = crop[mask > 0]
    span = np.ptp(truth, axis=0)  # how much the ramp changes across the hole, per channel
    ref_err = np.abs(ref - truth).mean(axis=0)
    assert (ref_err < 0.2 * span).all() and (np.abs(ref - truth).max(axis=0) < 0.5 * span).all()  # Telea is smooth
    for scale in (1.0, 0.5, 0.25):
        filled, inpainted = inpaint_atlas(atlas, observed, lay, tm, scale=scale)
        np.testing.assert_array_equal(inpainted, hole)  # walls and ceiling have no observations: left unfilled
        mine = filled[y0:y0 + h, x0:x0 + w][mask > 0]
        if scale == 1.0:
            assert np.abs(mine - ref).max() < 1e-4
        else:
            assert np.abs(mine - ref).mean() < 0.015, scale
        assert (np.abs(mine - truth).mean(axis=0) < 1.2 * ref_err + 1e-4).all(), scale


def test_no_bleeding_across_adjacent_surfaces():
    lay, tm = _room(L_SHAPE, d=16.0, padding=1)  # rectangles only 2 texels apart
    colours = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0, 1, 1], [1, 0, 1], [1, 1, 1], [0, 0, 0]],
                       np.float32)
    atlas = np.full((lay.height, lay.width, 3), 5.0, np.float32)  # gaps: a value no surface has
    atlas[tm.valid] = colours[tm.surface[tm.valid]]
    cols = np.arange(lay.width)[None, :]
    observed = np.zeros(tm.valid.shape, bool)
    for s in lay.surfaces:  # the left half of every rectangle: holes reach the edge next to a neighbour
        x0, y0, w, h = s.rect
        observed[y0:y0 + h, x0:x0 + w] = (cols[:, x0:x0 + w] < x0 + w // 2)
    observed &= tm.valid
    for scale in (0.25, 1.0):
        filled, inpainted = inpaint_atlas(atlas, observed, lay, tm, scale=scale)
        assert inpainted.sum() > 0.3 * tm.valid.sum()
        np.testing.assert_allclose(filled[inpainted], colours[tm.surface[inpainted]], atol=1e-4)
    # the setup does discriminate: one Telea pass over the whole atlas mixes neighbouring surfaces
    whole = _cv2_telea(atlas, (~observed).astype(np.uint8))
    hole = tm.valid & ~observed
    assert np.abs(whole[hole] - colours[tm.surface[hole]]).max() > 0.2


def _walls_seen(lay, tm, top_colour=(0.5, 0.5, 0.5)):
    """Atlas whose walls are observed in their upper 60 %; the lowest observed 20 % of wall i in
    colour ``first[i]`` along its first half and ``second[i]`` along its second half."""
    rng = np.random.default_rng(5)
    first, second = rng.uniform(0.1, 0.9, (2, len(lay.walls), 3)).astype(np.float32)
    atlas = np.zeros((lay.height, lay.width, 3), np.float32)
    observed = np.zeros(tm.valid.shape, bool)
    for i, s in enumerate(lay.walls):
        x0, y0, w, h = s.rect
        atlas[y0:y0 + h, x0:x0 + w] = top_colour
        atlas[y0 + int(0.4 * h):y0 + h, x0:x0 + w // 2] = first[i]
        atlas[y0 + int(0.4 * h):y0 + h, x0 + w // 2:x0 + w] = second[i]
        observed[y0:y0 + int(0.6 * h), x0:x0 + w] = True
    return atlas, observed & tm.core, (first, second)


@pytest.mark.parametrize("poly", [RECT, L_SHAPE], ids=["rect", "l_shape"])
def test_unseen_floor_is_propagated_from_the_walls(poly):
    lay, tm = _room(poly, d=40.0)  # at scale 0.25: 10 inpainting pixels per metre
    atlas, observed, (first, second) = _walls_seen(lay, tm)
    kinds = [s.kind for s in lay.surfaces]
    floor, ceiling = kinds.index("floor"), kinds.index("ceiling")
    filled, inpainted = inpaint_atlas(atlas, observed, lay, tm)
    np.testing.assert_array_equal(inpainted & (tm.surface == floor), tm.surface == floor)
    assert not inpainted[tm.surface == ceiling].any()  # an unseen ceiling stays unfilled
    # floor texels next to wall i, a quarter of the way along it, take the wall's bottom colour there
    xy = tm.position[..., :2].astype(float)
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        for where, colour in ((0.25, first[i]), (0.75, second[i])):
            near = (tm.surface == floor) & tm.core & (np.linalg.norm(xy - (a + where * (b - a)), axis=2) < 0.1)
            assert near.sum() > 3
            np.testing.assert_allclose(filled[near], np.broadcast_to(colour, (near.sum(), 3)), atol=0.06,
                                       err_msg=f"wall {i} at {where}")
    # the interior is a blend of the walls' bottom colours, never the grey top of the walls or black
    both = np.concatenate([first, second])
    inner = filled[(tm.surface == floor) & tm.core]
    assert (inner >= both.min(0) - 0.02).all() and (inner <= both.max(0) + 0.02).all()


def test_floor_propagation_only_when_floor_unseen_and_walls_seen():
    lay, tm = _room(RECT)
    floor = [s.kind for s in lay.surfaces].index("floor")
    atlas, observed, _ = _walls_seen(lay, tm)
    # no wall seen either: nothing to propagate, the floor stays unfilled
    none = np.zeros_like(observed)
    filled, inpainted = inpaint_atlas(atlas, none, lay, tm)
    assert not inpainted.any()
    np.testing.assert_array_equal(_bits(filled), _bits(atlas))
    # a floor with one observed patch is inpainted from itself only
    fx0, fy0 = lay.surfaces[floor].rect[:2]
    atlas[tm.surface == floor] = (0.3, 0.2, 0.1)
    observed[fy0 + 10:fy0 + 20, fx0 + 10:fx0 + 20] = True
    filled, inpainted = inpaint_atlas(atlas, observed, lay, tm)
    on_floor = inpainted & (tm.surface == floor)
    assert on_floor.sum() == (tm.surface == floor).sum() - 100
    np.testing.assert_allclose(filled[on_floor], np.broadcast_to([0.3, 0.2, 0.1], (on_floor.sum(), 3)), atol=1e-4)


def test_incremental_reruns_only_on_enough_change():
    lay, tm = _room(RECT)
    rng = np.random.default_rng(2)
    atlas = rng.random((lay.height, lay.width, 3)).astype(np.float32)
    observed = _blocks(tm.valid.shape, rng, p=0.3) & tm.valid
    inc = IncrementalInpainter(lay, tm, min_new_texels=50, scale=0.5)
    first = inc.update(atlas, observed)
    assert first is not None and inc.runs == 1
    direct = inpaint_atlas(atlas, observed, lay, tm, scale=0.5)
    np.testing.assert_array_equal(first[0], direct[0])
    np.testing.assert_array_equal(first[1], direct[1])
    assert inc.update(atlas, observed.copy()) is None
    free = np.argwhere(tm.valid & ~observed)
    grown = observed.copy()
    grown[free[:30, 0], free[:30, 1]] = True
    assert not inc.changed(grown) and inc.update(atlas, grown) is None  # 30 < 50 new texels
    grown[free[30:60, 0], free[30:60, 1]] = True
    assert inc.changed(grown) and inc.runs == 1
    again = inc.update(atlas, grown)  # 60 texels changed since the last run
    assert again is not None and inc.runs == 2
    assert not again[1][free[:60, 0], free[:60, 1]].any()  # newly observed texels are no longer inpainted
    assert inc.update(atlas, grown) is None
    assert inc.update(atlas, grown, force=True) is not None and inc.runs == 3
    shrunk = grown.copy()  # changes count both ways (e.g. a texel un-marked by a reset)
    shrunk[free[:50, 0], free[:50, 1]] = False
    assert inc.changed(shrunk)
    _, inpainted = inc.run(atlas, shrunk)
    assert inc.runs == 4 and not inc.changed(shrunk) and inpainted[free[:50, 0], free[:50, 1]].all()


def test_bad_arguments_raise():
    lay, tm = _room(RECT)
    atlas = np.zeros((lay.height, lay.width, 3), np.float32)
    observed = np.zeros((lay.height, lay.width), bool)
    with pytest.raises(SchemaError, match="atlas"):
        inpaint_atlas(atlas.astype(np.float64), observed, lay, tm)
    with pytest.raises(SchemaError, match="atlas"):
        inpaint_atlas(atlas[:-1], observed, lay, tm)
    with pytest.raises(SchemaError, match="observed"):
        inpaint_atlas(atlas, observed.astype(np.uint8), lay, tm)
    with pytest.raises(SchemaError, match="scale"):
        inpaint_atlas(atlas, observed, lay, tm, scale=0.0)
    with pytest.raises(SchemaError, match="min_new_texels"):
        IncrementalInpainter(lay, tm, min_new_texels=0)
