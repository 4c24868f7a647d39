"""HDR expansion of the coarse model's atlas (probeless.hdr.coarse), HDR cubemaps and ``probeless eval hdr-envmap``.

Measured on convex_room (the true-atlas test below: the true LDR atlas at 256 texels, photo aimed at the
over-exposed points, pmatch-rgb, 2 views of 96 px): irradiance error against the linear truth at the sphere
0.571 for the LDR map and 0.364 for the HDR one; the eval with the CLI test's small settings (photo aimed at the
atlas's over-exposed texels, the default): 0.520 vs 0.210 (sphere) and 0.396 vs 0.184 (probe_b).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from locations import REPO

from probeless.coarse.atlas import fit_atlas, layout_atlas
from probeless.coarse.texels import texel_map
from probeless.color import srgb_to_linear
from probeless.errors import HdrError, ProbelessError
from probeless.hdr.coarse import atlas_linear, dense_linear, expand_atlas, fill_ring, texel_cloud
from probeless.hdr.transfer import overexposed

L_SHAPE = np.array([[0, 0], [4, 0], [4, 2], [2, 2], [2, 3.5], [0, 3.5]], float)
SCENE = REPO / "launch" / "scenes" / "convex_room.yaml"


@pytest.fixture(scope="module")
def small():
    """(layout, texmap, rgba8 atlas with random colours, ~70 % observed, some over-exposed texels)."""
    layout = layout_atlas(L_SHAPE, 2.5, 12.0)
    tm = texel_map(layout)
    rng = np.random.default_rng(3)
    atlas = rng.integers(0, 256, (layout.height, layout.width, 4)).astype(np.uint8)
    atlas[..., 3] = np.where(rng.random(atlas.shape[:2]) < 0.7, 255, 0)
    atlas[rng.random(atlas.shape[:2]) < 0.05, :3] = 255  # saturated texels
    return layout, tm, atlas


def texel_centres(layout) -> dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]:
    """{(row, col): (centre, normal)} of every texel inside a surface's rectangle, by atlas.py's formula."""
    d = layout.texels_per_m
    out = {}
    for s in layout.surfaces:
        x0, y0, w, h = s.rect
        for r in range(y0, y0 + h):
            for c in range(x0, x0 + w):
                out[r, c] = (s.origin + s.u_axis * (c - x0 + 0.5) / d + s.v_axis * (r - y0 + 0.5) / d, s.normal)
    return out


def test_texel_cloud_is_the_observed_core_texels_at_their_centres(small):
    layout, tm, atlas = small
    cloud = texel_cloud(atlas, tm)
    want = (atlas[..., 3] > 0) & tm.core
    got = np.zeros_like(want)
    got[cloud.rows, cloud.cols] = True
    np.testing.assert_array_equal(got, want)
    centres = texel_centres(layout)
    ref = np.array([centres[r, c][0] for r, c in zip(cloud.rows, cloud.cols)])
    nrm = np.array([centres[r, c][1] for r, c in zip(cloud.rows, cloud.cols)])
    np.testing.assert_allclose(cloud.points, ref, atol=1e-5)  # float32 positions
    np.testing.assert_array_equal(cloud.normals, nrm.astype(np.float32))
    np.testing.assert_allclose(cloud.colors, srgb_to_linear(atlas[cloud.rows, cloud.cols, :3] / 255.0), atol=1e-6)
    assert len(np.unique(cloud.points, axis=0)) == len(cloud.points)  # no duplicate positions


def test_atlas_round_trip_keeps_texels_and_non_overexposed_values(small):
    layout, tm, atlas = small
    hdr = expand_atlas(atlas, tm, None, method="landis-pc", max_lum=10.0)
    ldr = atlas_linear(atlas)
    assert hdr.radiance.shape == ldr.shape and hdr.radiance.dtype == np.float32
    # the cloud's values land back on exactly the texels they came from
    np.testing.assert_array_equal(hdr.radiance[hdr.cloud.rows, hdr.cloud.cols], hdr.result.radiance)
    over = overexposed(ldr)
    np.testing.assert_array_equal(hdr.radiance[~over], ldr[~over])
    seen = atlas[..., 3] > 0
    unseen = ~seen & tm.valid
    np.testing.assert_array_equal(hdr.radiance[unseen], ldr[unseen])  # inpainted / unseen: linear LDR kept
    core_over = over & seen & tm.core
    assert core_over.sum() > 50 and (hdr.radiance[core_over] > ldr[core_over] + 1e-3).all()
    assert hdr.report["texels_cloud"] == len(hdr.cloud.points) == int((seen & tm.core).sum())


def test_fill_ring_copies_the_nearest_core_texel_of_the_same_surface():
    layout = layout_atlas(np.array([[0, 0], [3, 0], [3, 2], [0, 2]], float), 2.0, 10.0)
    tm = texel_map(layout)
    ldr = np.full((layout.height, layout.width, 3), 0.2, np.float32)
    radiance = ldr.copy()
    s = layout.surface("wall0")
    x0, y0, w, h = s.rect
    ldr[y0:y0 + h, x0 - 2:x0 + 1] = 1.0                 # the wall's left edge column and its ring: saturated
    radiance[y0:y0 + h, x0] = 7.0                      # the edge texels got an HDR value
    seen = tm.valid.copy()
    done = fill_ring(radiance, ldr, tm, seen)
    ring = done[y0:y0 + h, x0 - 2:x0]
    assert ring.all() and done.sum() == ring.size
    np.testing.assert_array_equal(radiance[y0:y0 + h, x0 - 2:x0], 7.0)


def test_errors_name_the_thing_at_fault(small):
    layout, tm, atlas = small
    with pytest.raises(HdrError, match="no observed texel"):
        expand_atlas(np.zeros_like(atlas), tm, None, method="landis-pc", max_lum=10.0)
    with pytest.raises(HdrError, match="texel map"):
        texel_cloud(atlas[:-1], tm)
    with pytest.raises(HdrError, match="alpha"):
        texel_cloud(atlas[..., :3], tm)
    with pytest.raises(HdrError, match="delta"):
        dense_linear(np.zeros((3, 3), np.uint8), delta=(0, 1))
    from probeless.hdr.synthetic import synthetic_case

    with pytest.raises(HdrError, match="photo_target point"):
        synthetic_case(SCENE, photo_target=(1.0, 2.0))


def test_dense_linear_applies_delta_then_decodes():
    c = np.array([[0, 128, 255]], np.uint8)
    np.testing.assert_allclose(dense_linear(c), srgb_to_linear(c / 255.0), atol=1e-6)
    np.testing.assert_allclose(dense_linear(c, (0.1, -0.1, 0.2)),
                               srgb_to_linear(np.clip(c / 255.0 + [0.1, -0.1, 0.2], 0, 1)), atol=1e-6)


@pytest.mark.gl
def test_renderer_draws_linear_atlas_and_dense_unclipped():
    from probeless.envmap.cubemap import EnvmapRenderer

    layout = layout_atlas(np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float), 2.5, 8.0)
    r = EnvmapRenderer(layout)
    try:
        r.set_atlas(np.full((layout.height, layout.width, 3), 6.5, np.float32), linear=True)
        faces = r.render((2.0, 2.0, 1.2), 16, dense=False)
        np.testing.assert_allclose(faces, 6.5, rtol=1e-6)
        r.set_atlas(np.full((layout.height, layout.width, 3), 6.5, np.float32))  # LDR path: clipped to 1
        np.testing.assert_allclose(r.render((2.0, 2.0, 1.2), 16, dense=False), 1.0)
        pts = np.array([[2.0, 2.0, 2.0]], np.float32)  # right above: the +Z face's centre
        r.set_dense(pts, np.array([[3.0, 4.0, 5.0]], np.float32), linear=True)
        up = r.render((2.0, 2.0, 1.2), 16, splat_m=0.2)[4]
        assert np.allclose(up.reshape(-1, 3).max(axis=0), [3.0, 4.0, 5.0])
        r.set_dense(pts, np.array([[0.5, 0.5, 0.5]], np.float32))
        assert r.render((2.0, 2.0, 1.2), 16, splat_m=0.2)[4].max() == 1.0  # LDR atlas (clipped 6.5) around
        with pytest.raises(ProbelessError, match="linear radiance"):
            r.set_atlas(np.zeros((layout.height, layout.width, 3), np.uint8), linear=True)
        with pytest.raises(ProbelessError, match="finite"):
            r.set_dense(pts, np.array([[-1.0, 0, 0]], np.float32), linear=True)
    finally:
        r.release()


@pytest.mark.gl
@pytest.mark.slow
def test_hdr_true_atlas_lowers_the_irradiance_error_against_linear_truth():
    from probeless.coarse.truth import true_atlas
    from probeless.envmap.cubemap import EnvmapRenderer
    from probeless.eval.hdr_envmap import score_linear
    from probeless.hdr.synthetic import synthetic_case
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import Rig

    scene = load_scene(SCENE)
    case = synthetic_case(SCENE, frames=4, scale=0.2, voxel=0.03)
    rig = Rig(scene, envmap_size=32, envmaps=False)
    layout = fit_atlas(scene.floorplan, scene.ceiling_height, 256)
    renderer = EnvmapRenderer(layout, ctx=rig.renderer.ctx)
    try:
        t = scene.duration
        ldr = true_atlas(rig.renderer, layout, rig.light_scale(t), scene.fisheye.exposure)
        tm = texel_map(layout)
        hdr = expand_atlas(ldr, tm, case.photo_hdr, observed=tm.core, views=2, size=96)
        pos = np.asarray(scene.virtual_objects[0].position, float)
        truth = rig.render_envmap(pos, t) * np.float32(scene.fisheye.exposure)
        renderer.set_atlas(ldr)
        est_ldr = srgb_to_linear(np.clip(renderer.render(pos, 32, dense=False), 0, 1))
        renderer.set_atlas(hdr.radiance, linear=True)
        est_hdr = renderer.render(pos, 32, dense=False)
    finally:
        renderer.release()
        rig.release()
    e_ldr, e_hdr = score_linear(est_ldr, truth), score_linear(est_hdr, truth)
    assert e_ldr["irradiance_rel_error"] > 0.5  # measured 0.571 (LDR) vs 0.364 (HDR)
    assert e_hdr["irradiance_rel_error"] < e_ldr["irradiance_rel_error"] - 0.15
    assert e_hdr["power_ratio"] > e_ldr["power_ratio"] + 0.1  # 0.646 vs 0.460
    assert e_hdr["peak_ratio"] > 5 * e_ldr["peak_ratio"]  # 0.547 vs 0.042: the lamps keep their strength
    assert e_hdr["log_rmse_stops"] < e_ldr["log_rmse_stops"]  # 0.894 vs 1.049


@pytest.mark.gl
@pytest.mark.slow
def test_eval_hdr_envmap_json_scores_ldr_and_hdr_maps(capsys):
    from probeless.cli import main

    args = ["eval", "hdr-envmap", str(SCENE), "--stride", "8", "--rgbd-stride", "12", "--atlas-size", "128",
            "--size", "96", "--views", "2", "--face-size", "32", "--json", "--no-progress"]
    assert main(args) == 0
    out = capsys.readouterr().out
    res = json.loads(out)
    assert out.count("\n") == 1 and "oracle" in res["poses"] and "linear" in res["units"]["truth"]
    (scene,) = res["scenes"]
    assert len(scene["photo_target"]) == 3 and scene["atlas"]["points_expanded"] > 0  # aimed at the atlas
    for per in scene["objects"].values():
        assert set(per) == {"ldr", "hdr_coarse", "hdr", "truth_peak"}
        assert per["hdr"]["irradiance_rel_error"] < per["ldr"]["irradiance_rel_error"] - 0.15
        assert per["hdr"]["power_ratio"] > per["ldr"]["power_ratio"]
