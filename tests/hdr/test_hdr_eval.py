"""Synthetic HDR-expansion ground truth (probeless.hdr.synthetic) and ``probeless eval hdr-expand``.

The eval lights a diffuse and a GGX sphere by the cubemap of each cloud through the IBL renderer; here the
pieces are checked against independent references: a constant environment (analytic radiance L x albedo),
linearity of the rendering in the cloud's
colours (k x truth has RMS |k - 1| x the truth's RMS), clipping (LDR lights the GGX sphere less, pixel by
pixel). On light_switch with the test's small settings (SMALL) ``pmatch-rgb`` beats ``ldr`` on the
over-exposed cloud RMS and on both renderings, with the cubemap and with the PBGI renderer (``--renderer pbgi``,
whose spheres cover the cubemap path's pixels and, with one tree for every cloud, are linear in the radiance).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from locations import REPO

from probeless.cli import main
from probeless.hdr.expand import METHODS
from probeless.hdr.transfer import overexposed

SCENE = REPO / "launch" / "scenes" / "light_switch.yaml"
SMALL = ["--frames", "4", "--scale", "0.2", "--voxel", "0.03", "--views", "2", "--size", "96", "--face", "32",
         "--image", "64"]
KEYS = ("cloud_rms", "cloud_rms_overexposed", "diffuse_rms", "diffuse_ssim", "ggx_rms", "ggx_ssim")


@pytest.fixture(scope="module")
def case():
    from probeless.hdr.synthetic import synthetic_case

    return synthetic_case(SCENE, frames=4, scale=0.2, voxel=0.03, exposure=1.0)


@pytest.fixture(scope="module")
def ctx():
    from probeless.gl.context import create_context

    c = create_context()
    yield c
    c.release()


def make_objects(ctx, centre=(0.0, 0.0, 1.0), radius=0.12, size=64, roughness=0.3,
                 towards=((1.0, 3.0, 1.4), (3.0, -1.0, 1.6))):
    from probeless.eval.hdr_expand import viewpoints
    from probeless.ibl.probes import ProbeRenderer

    cams = viewpoints(centre, radius, towards, size)
    return ProbeRenderer(ctx, centre, radius, roughness, cams, size), cams


def cube(size: int, fn) -> np.ndarray:
    from probeless.geom.cube import cube_directions

    return fn(cube_directions(size)).astype(np.float32)


# --- synthetic case ----------------------------------------------------------------------------------

@pytest.mark.gl
def test_synthetic_ldr_is_the_clipped_exposed_truth_with_overexposed_points(case):
    assert case.points.shape == case.true_radiance.shape == case.ldr_colors.shape
    assert case.points.dtype == case.true_radiance.dtype == case.ldr_colors.dtype == np.float32
    np.testing.assert_array_equal(case.ldr_colors, np.clip(np.float32(case.exposure) * case.true_radiance, 0, 1))
    assert case.true_radiance.max() > 1.0 and overexposed(case.ldr_colors).sum() > 100
    assert case.photo_hdr.dtype == np.float32 and case.photo_hdr.ndim == 3 and case.photo_hdr.max() > 0.37
    assert np.isfinite(case.true_radiance).all() and case.true_radiance.min() >= 0


@pytest.mark.gl
def test_synthetic_case_is_deterministic(case):
    from probeless.hdr.synthetic import synthetic_case

    again = synthetic_case(SCENE, frames=4, scale=0.2, voxel=0.03, exposure=1.0)
    np.testing.assert_array_equal(again.points, case.points)
    np.testing.assert_array_equal(again.true_radiance, case.true_radiance)
    np.testing.assert_array_equal(again.photo_hdr, case.photo_hdr)


def test_synthetic_case_rejects_an_unknown_photo_target():
    from probeless.errors import HdrError
    from probeless.hdr.synthetic import synthetic_case

    with pytest.raises(HdrError, match="photo_target"):
        synthetic_case(SCENE, photo_target="ceiling")


# --- the two objects ----------------------------------------------------------------

@pytest.mark.gl
def test_spheres_under_a_constant_environment_have_its_radiance(ctx):
    """Lambertian albedo 1 under constant radiance L: outgoing radiance L x albedo = L (analytic); the GGX
    sphere (colour 1) reflects L too."""
    objects, cams = make_objects(ctx)
    try:
        L = np.array([0.7, 1.3, 2.5])
        out = objects.render(np.full((6, 32, 32, 3), L, np.float32))
    finally:
        objects.release()
    for kind in ("diffuse", "ggx"):
        assert len(out[kind]) == 2
        for img, mask in out[kind]:
            assert mask.sum() > 0.3 * mask.size and not mask[0].any() and not mask[:, 0].any()
            np.testing.assert_allclose(img[mask], np.broadcast_to(L, img[mask].shape), rtol=2e-3)
            assert np.all(img[~mask] == 0)


def test_viewpoints_look_at_the_object_from_4_radii_towards_each_target():
    from probeless.eval.hdr_expand import VIEW_FILL, viewpoints

    centre, radius = np.array([2.0, 2.0, 0.9]), 0.12
    towards = [(1.0, 3.2, 1.4), (3.5, 3.2, 1.4)]
    cams = viewpoints(centre, radius, towards, 128)
    assert len(cams) == 2
    for (K, pose), t in zip(cams, towards):
        d = np.asarray(t) - centre
        np.testing.assert_allclose(pose[:3, 3], centre + 0.48 * d / np.linalg.norm(d), atol=1e-9)
        np.testing.assert_allclose(pose[:3, 2], -d / np.linalg.norm(d), atol=1e-9)  # optical axis at the centre
        # the silhouette (tangent cone, half-angle asin(r / dist)) spans VIEW_FILL of the width
        span = 2 * K[0, 0] * np.tan(np.arcsin(radius / 0.48))
        assert span == pytest.approx(VIEW_FILL * 128, rel=1e-6)


LIT_TOWARDS = ((1.0, 3.2, 1.4), (3.5, 3.2, 1.4))  # the viewpoints' targets of ``lit``


def viewpoints_of_lit(case):
    """The cameras of the ``lit`` renderings."""
    from probeless.eval.hdr_expand import viewpoints

    return viewpoints(case.object_position, 0.12, LIT_TOWARDS, 64)


@pytest.fixture(scope="module")
def lit(case, ctx):
    """Renderings (face 32, 64 px) of the spheres at the case's object lit by the true cloud, 1.1 x the true
    cloud and the LDR colours."""
    from probeless.hdr.splat import SplatRenderer, cloud_cubemap, point_spacing

    truth = case.truth_cloud_units
    splat = SplatRenderer(ctx)
    objects, _ = make_objects(ctx, case.object_position, 0.12, towards=LIT_TOWARDS)
    spacing = point_spacing(case.points)
    try:
        out, covered = {}, {}
        for name, colors in (("truth", truth), ("scaled", 1.1 * truth), ("ldr", case.ldr_colors)):
            faces, covered[name] = cloud_cubemap(splat, case.points, colors, spacing, case.object_position, 32)
            out[name] = objects.render(faces)
    finally:
        objects.release()
        splat.release()
    for name in ("scaled", "ldr"):
        np.testing.assert_array_equal(covered[name], covered["truth"])  # holes are the same texels
    assert 0.05 < 1 - covered["truth"].mean() < 0.95  # the small cloud leaves holes (both sides 0 there)
    return out


@pytest.mark.gl
def test_the_truth_scores_rms_0_and_ssim_1_against_itself(lit):
    from probeless.eval.hdr_expand import compare_renderings

    res = compare_renderings(lit["truth"], lit["truth"])
    assert len(res["views"]) == 2
    for key in ("diffuse_rms", "ggx_rms"):
        assert res[key] == 0.0
    for key in ("diffuse_ssim", "ggx_ssim"):
        assert res[key] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.gl
def test_rendering_rms_is_linear_in_the_cloud_scale_and_ldr_is_darker(lit):
    """Rendering is linear in the cubemap: 1.1 x truth gives RMS 0.1 x the truth's RMS over the mask. The LDR
    colours are the truth clipped, so they light the GGX sphere (positive lobe weights) no brighter anywhere,
    and the baseline's RMS is well above 0."""
    from probeless.eval.hdr_expand import compare_renderings

    scaled = compare_renderings(lit["scaled"], lit["truth"])
    ldr = compare_renderings(lit["ldr"], lit["truth"])
    for kind in ("diffuse", "ggx"):
        for i, (img, mask) in enumerate(lit["truth"][kind]):
            expected = 0.1 * np.sqrt(np.mean(img[mask] ** 2))
            assert scaled["views"][i][f"{kind}_rms"] == pytest.approx(expected, rel=1e-4)
            assert ldr["views"][i][f"{kind}_rms"] > 0.03
        assert ldr[f"{kind}_rms"] > scaled[f"{kind}_rms"] > 0  # clipping costs more than a 10 % scale error
        assert scaled[f"{kind}_ssim"] < 1.0
    for (a, mask), (b, _) in zip(lit["ldr"]["ggx"], lit["truth"]["ggx"]):
        assert np.all(a[mask] <= b[mask] * (1 + 1e-5) + 1e-6) and np.mean(a[mask] < b[mask] - 0.05) > 0.05


@pytest.mark.gl
def test_the_two_viewpoints_see_different_ggx_reflections(lit):
    (a, ma), (b, mb) = lit["truth"]["ggx"]
    both = ma & mb
    assert both.mean() > 0.3
    # a glossy sphere shows a different part of the room from each side; the diffuse one changes less
    ggx_change = np.abs(a[both] - b[both]).mean() / b[both].mean()
    (c, _), (d, _) = lit["truth"]["diffuse"]
    diffuse_change = np.abs(c[both] - d[both]).mean() / d[both].mean()
    assert ggx_change > 0.2 and ggx_change > diffuse_change


# --- the CLI --------------------------------------------------------------------------------------------

@pytest.mark.gl
def test_eval_ldr_json_pictures_and_figure(case, tmp_path, capsys):
    args = ["eval", "hdr-expand", str(SCENE), *SMALL, "--methods", "ldr", "--json", "--no-progress",
            "--pictures", str(tmp_path / "pics"), "--figure", str(tmp_path / "bars.png")]
    assert main(args) == 0
    res = json.loads(capsys.readouterr().out)
    (scene,) = res["scenes"]
    assert res["roughness"] == 0.3 and res["image"] == 64 and res["face"] == 32 and set(res["units"]) >= {"ggx_rms"}
    assert res["renderer"] == "cubemap" and "pbgi" not in res and 0 < scene["cubemap_hole_fraction"] < 1
    row = scene["methods"]["ldr"]
    truth = case.truth_cloud_units.astype(np.float64)
    assert row["cloud_rms"] == pytest.approx(np.sqrt(np.mean((case.ldr_colors - truth) ** 2)), abs=1e-6)
    assert len(row["views"]) == len(scene["viewpoints"]) == 2
    for key in KEYS[2:]:
        assert row[key] == pytest.approx(np.mean([v[key] for v in row["views"]]), abs=2e-6)
    assert 0 < row["diffuse_rms"] and 0 < row["ggx_rms"] and row["ggx_ssim"] < 1
    for name in ("pics/light_switch.png", "bars.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert scene["pictures"] == str(tmp_path / "pics" / "light_switch.png")
    from probeless.eval.hdr_expand import format_table

    table = format_table(res)
    assert "ggx ssim" in table and f"{row['ggx_rms']:.4g}" in table and "roughness 0.3" in table


@pytest.mark.gl
@pytest.mark.slow
def test_eval_json_has_every_method_and_pmatch_beats_ldr_on_overexposed(capsys):
    assert main(["eval", "hdr-expand", str(SCENE), *SMALL, "--json", "--no-progress"]) == 0
    out = capsys.readouterr().out
    res = json.loads(out)
    assert out.count("\n") == 1 and res["methods"] == ["ldr", *METHODS]
    (scene,) = res["scenes"]
    assert set(scene["methods"]) == {"ldr", *METHODS}
    for row in scene["methods"].values():
        for key in KEYS:
            assert np.isfinite(row[key]), key
        assert len(row["views"]) == 2
    rows = scene["methods"]
    assert rows["pmatch-rgb"]["cloud_rms_overexposed"] < rows["ldr"]["cloud_rms_overexposed"]
    assert rows["pmatch-rgb"]["diffuse_rms"] < rows["ldr"]["diffuse_rms"]
    assert rows["pmatch-rgb"]["ggx_rms"] < rows["ldr"]["ggx_rms"]


@pytest.mark.gl
def test_pbgi_spheres_cover_the_cubemap_spheres_pixels_and_are_linear_in_the_radiance(case, ctx, lit):
    """PbgiProbes draws the spheres of ProbeRenderer (same mesh, cameras, size: the same pixels), lit by the
    points themselves. With the default tc = 0 every cloud gets the same tree, so the rendering is linear in the
    radiance: 1.1 x the truth gives RMS 0.1 x the truth's RMS (and the truth against itself 0)."""
    from probeless.eval.hdr_expand import compare_renderings
    from probeless.eval.hdr_pbgi import VARIANTS, PbgiProbes
    from probeless.pbgi.microbuffer import VARIANTS as ALL_VARIANTS

    assert set(VARIANTS) == set(ALL_VARIANTS) - {"envmap"}
    cams = viewpoints_of_lit(case)
    probes = PbgiProbes(ctx, case.points, case.object_position, 0.12, 0.3, cams, 64)
    try:
        assert probes.normals.shape == case.points.shape and probes.scene_info() == {}
        a = probes.render(case.truth_cloud_units)
        scaled = compare_renderings(probes.render(1.1 * case.truth_cloud_units), a)
    finally:
        probes.release()
    assert scaled["ggx_ssim"] < 1
    for kind in ("diffuse", "ggx"):
        for i, ((img, mask), (_, cube_mask)) in enumerate(zip(a[kind], lit["truth"][kind])):
            np.testing.assert_array_equal(mask, cube_mask)
            assert np.all(img[~mask] == 0) and np.isfinite(img).all() and img[mask].max() > 0.1
            expected = 0.1 * np.sqrt(np.mean(img[mask] ** 2))
            assert scaled["views"][i][f"{kind}_rms"] == pytest.approx(expected, rel=1e-4)


@pytest.mark.slow
@pytest.mark.gl
def test_eval_pbgi_renderer_json_and_pmatch_beats_ldr(capsys):
    """``--renderer pbgi``: the same metrics per viewpoint, the settings recorded; pmatch-rgb beats ldr on both
    renderings there too (as with the cubemap: test_eval_json_has_every_method_and_pmatch_beats_ldr_on_overexposed)."""
    args = ["eval", "hdr-expand", str(SCENE), *SMALL, "--methods", "ldr", "pmatch-rgb", "--renderer", "pbgi",
            "--variant", "hybrid", "--micro", "16", "--json", "--no-progress"]
    assert main(args) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["renderer"] == "pbgi" and res["pbgi"] == {"variant": "hybrid", "micro": 16, "tc": 0.0}
    assert "face" not in res
    (scene,) = res["scenes"]
    assert "cubemap_hole_fraction" not in scene
    rows = scene["methods"]
    for row in rows.values():
        for key in KEYS:
            assert np.isfinite(row[key]), key
        assert len(row["views"]) == 2
        for key in KEYS[2:]:
            assert row[key] == pytest.approx(np.mean([v[key] for v in row["views"]]), abs=2e-6)
    assert rows["ldr"]["ggx_rms"] > 0.05 and rows["ldr"]["ggx_ssim"] < 1
    assert rows["pmatch-rgb"]["diffuse_rms"] < rows["ldr"]["diffuse_rms"]
    assert rows["pmatch-rgb"]["ggx_rms"] < rows["ldr"]["ggx_rms"]


def test_eval_rejects_an_unknown_method(capsys):
    assert main(["eval", "hdr-expand", str(SCENE), "--methods", "ldr", "nope", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "unknown method 'nope'" in err and "pmatch-rgb" in err


def test_luminance_ratios_by_hand():
    from probeless.eval.hdr_expand import luminance_ratios

    truth = np.full((5, 3), 2.0, np.float32)
    est = truth * np.array([1.0, 1.0, 0.25, 3.0, 1.5], np.float32)[:, None]  # grey: luminance scales alike
    r = luminance_ratios(est, truth)
    assert r["overexposed_ratio_median"] == pytest.approx(1.0)
    assert r["overexposed_over_2x"] == pytest.approx(0.2) and r["overexposed_under_half"] == pytest.approx(0.2)
    assert set(luminance_ratios(est[:0], truth[:0]).values()) == {None}
