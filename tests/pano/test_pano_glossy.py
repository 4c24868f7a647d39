"""Glossy ring sampling, mip chain and trilinear lookups against analytic integrals, OpenCV and scipy."""

import argparse
import json

import cv2
import numpy as np
import pytest
from scipy import integrate, ndimage

from probeless.errors import ProbelessError
from probeless.eval import add_evaluation
from probeless.pano import equirect, glossy
from probeless.pano.glossy_eval import evaluate_glossy, glossy_fis, random_directions
from probeless.pano.glossy_figure import glossy_spheres

ROUGH = (0.01, 0.05, 0.1, 0.2, 0.5)


def rand_env(h, seed=0):
    return np.random.default_rng(seed).random((h, 2 * h, 3)).astype(np.float32)


def linear_env(h, tint=(1.0, 0.5, -0.5)):
    """L(w) = 1 + w.z (per channel: 1 + tint_c w.z) sampled at the pixel centres."""
    z = equirect.pixel_directions(2 * h, h)[..., 2:3]
    return (1.0 + z * np.asarray(tint)).astype(np.float32)


def reference_bilinear(img, dirs):
    """scipy map_coordinates (order 1) on the image padded by wrapping columns and repeating edge rows."""
    h, w = img.shape[:2]
    u, v = equirect.direction_to_pixel(dirs, w, h)
    pad = np.pad(np.pad(img, ((0, 0), (1, 1), (0, 0)), mode="wrap"), ((1, 1), (0, 0), (0, 0)), mode="edge")
    coords = [v - 0.5 + 1.0, u - 0.5 + 1.0]
    return np.stack([ndimage.map_coordinates(pad[..., c].astype(np.float64), coords, order=1, mode="nearest")
                     for c in range(img.shape[2])], axis=-1)


def test_phong_exponent_and_lobe_half_angle():
    assert glossy.phong_exponent(0.1) == pytest.approx(198.0)
    assert glossy.phong_exponent(1.0) == 0.0
    for bad in (0.0, -0.2, 1.5, float("nan")):
        with pytest.raises(ProbelessError):
            glossy.phong_exponent(bad)
    for n in (1.0, 6.0, 198.0, 19998.0, 2e6):
        half = glossy.lobe_half_angle(n)
        assert np.cos(half) ** n == pytest.approx(0.5, rel=1e-9)
    assert glossy.lobe_half_angle(0.0) == pytest.approx(np.pi / 2)
    with pytest.raises(ProbelessError):
        glossy.lobe_half_angle(-1.0)


@pytest.mark.parametrize("rough", ROUGH)
def test_ring_pattern_structure(rough):
    h = 512
    p = glossy.ring_pattern(rough, h)
    half = glossy.lobe_half_angle(glossy.phong_exponent(rough))
    assert all(a.shape == (36,) and a.dtype == np.float32 for a in (p.angles, p.azimuths, p.weights, p.lods))
    radii, counts = np.unique(p.angles, return_counts=True)
    assert len(radii) == 6 and np.all(counts == 6)
    assert np.sum(radii < half) == 3 and np.sum(radii > half) == 3
    assert p.weights.sum() == pytest.approx(1.0, abs=1e-6) and np.all(p.weights > 0)
    assert np.all(p.lods >= 0) and np.all(np.diff(p.lods) >= 0)  # samples are ordered ring by ring
    step = 2 * np.pi / 6
    np.testing.assert_allclose(p.azimuths[6:12] - p.azimuths[:6], step / 2, atol=1e-6)  # rings turned by half a step
    # lod rule checked on the geometry: neighbouring samples' angular distance = texel spacing pi 2^lod / h
    d = glossy.ring_directions(np.array([[0.3, -0.4, 0.5]]), p)[0]
    gap = np.arccos(np.clip(np.sum(d[0::6] * d[1::6], axis=1), -1, 1))
    lod = p.lods[0::6]
    np.testing.assert_allclose(np.pi * 2.0 ** lod[lod > 0] / h, gap[lod > 0], rtol=1e-4)
    assert np.all(np.pi / h >= gap[lod == 0] - 1e-9)


def test_ring_weights_are_the_phong_mass_of_each_stratum():
    n = glossy.phong_exponent(0.5)
    half = glossy.lobe_half_angle(n)
    lobe = lambda t: np.cos(t) ** n * np.sin(t)  # noqa: E731
    inside = integrate.quad(lobe, 0, half)[0] / integrate.quad(lobe, 0, np.pi / 2)[0]
    p = glossy.ring_pattern(0.5, 256)
    np.testing.assert_allclose(p.weights[:18], inside / 18, rtol=1e-5)
    np.testing.assert_allclose(p.weights[18:], (1 - inside) / 18, rtol=1e-5)


def test_lods_grow_with_roughness():
    lods = np.array([glossy.ring_pattern(r, 512).lods for r in ROUGH])
    assert np.all(np.diff(lods, axis=0) >= 0) and np.all(np.diff(lods.sum(axis=1)) > 0)


def test_tangent_frame_orthonormal_including_poles():
    r = np.vstack([random_directions(50, 1), [[0, 0, 1], [0, 0, -1], [0.01, 0, 0.99995]]])
    t, b = glossy.tangent_frame(r)
    r = r / np.linalg.norm(r, axis=1, keepdims=True)
    for a, c in ((t, t), (b, b)):
        np.testing.assert_allclose(np.sum(a * c, axis=1), 1, atol=1e-12)
    for a, c in ((t, b), (t, r), (b, r)):
        np.testing.assert_allclose(np.sum(a * c, axis=1), 0, atol=1e-12)
    np.testing.assert_allclose(np.cross(t, b), r, atol=1e-12)


def test_ring_directions_unit_and_at_the_pattern_angles():
    r = random_directions(20, 2)
    p = glossy.ring_pattern(0.2, 256)
    d = glossy.ring_directions(r, p)
    assert d.shape == (20, 36, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1, atol=1e-12)
    ang = np.arccos(np.clip(np.einsum("nkc,nc->nk", d, r), -1, 1))
    np.testing.assert_allclose(ang, np.broadcast_to(p.angles, ang.shape), atol=1e-6)
    t, b = glossy.tangent_frame(r)
    az = np.arctan2(np.einsum("nkc,nc->nk", d, b), np.einsum("nkc,nc->nk", d, t))
    np.testing.assert_allclose(np.exp(1j * az), np.broadcast_to(np.exp(1j * p.azimuths), az.shape), atol=1e-5)


def test_mip_levels_match_cv2_area_halving():
    img = rand_env(64)
    levels = glossy.mip_levels(img)
    assert [lv.shape[0] for lv in levels] == [64, 32, 16, 8, 4, 2, 1]
    for a, b in zip(levels[:-1], levels[1:]):
        ref = cv2.resize(a, (a.shape[1] // 2, a.shape[0] // 2), interpolation=cv2.INTER_AREA)
        np.testing.assert_allclose(b, ref, rtol=1e-5, atol=1e-6)
    odd = glossy.mip_levels(rand_env(6))
    assert [lv.shape[:2] for lv in odd] == [(6, 12), (3, 6), (1, 2)]
    assert odd[2].mean() == pytest.approx(odd[0].mean(), rel=1e-5)  # area averaging keeps the mean
    with pytest.raises(ProbelessError):
        glossy.mip_levels(np.zeros((4, 7, 3), np.float32))


def test_sample_equirect_texel_centres_wrap_and_levels():
    img = rand_env(16, 3)
    levels = glossy.mip_levels(img)
    for lvl in (0, 1, 2):
        h = levels[lvl].shape[0]
        np.testing.assert_allclose(glossy.sample_equirect(levels, equirect.pixel_directions(2 * h, h), lvl),
                                   levels[lvl], atol=1e-6)
    dirs = random_directions(300, 4)
    np.testing.assert_allclose(glossy.sample_equirect(levels, dirs, 0), reference_bilinear(img, dirs), atol=1e-6)
    np.testing.assert_allclose(glossy.sample_equirect(levels, dirs, 1), reference_bilinear(levels[1], dirs), atol=1e-6)
    # the u seam (phi = 0): continuous, and halfway between the first and last columns
    th = (5 + 0.5) * np.pi / 16
    seam = np.array([[np.sin(th) * np.cos(e), np.sin(th) * np.sin(e), np.cos(th)] for e in (-1e-7, 0.0, 1e-7)])
    s = glossy.sample_equirect(levels, seam, 0)
    np.testing.assert_allclose(s, np.broadcast_to(0.5 * (img[5, 0] + img[5, -1]), s.shape), atol=1e-5)
    lo, hi = glossy.sample_equirect(levels, dirs, 2.0), glossy.sample_equirect(levels, dirs, 3.0)
    np.testing.assert_allclose(glossy.sample_equirect(levels, dirs, 2.25), 0.75 * lo + 0.25 * hi, atol=1e-6)
    per = np.linspace(-2, 9, len(dirs))  # per-direction lods, clamped to [0, 4]
    ref = [glossy.sample_equirect(levels, dirs[i:i + 1], np.clip(per[i], 0, 4))[0] for i in range(0, 300, 37)]
    np.testing.assert_allclose(glossy.sample_equirect(levels, dirs, per)[::37], ref, atol=1e-6)
    top = reference_bilinear(levels[-1], dirs)  # lod clamped to the last level
    np.testing.assert_allclose(glossy.sample_equirect(levels, dirs, 50.0), top, atol=1e-6)


def test_mirror_is_the_level0_bilinear_lookup():
    img = rand_env(32, 5)
    dirs = random_directions(100, 6)
    np.testing.assert_allclose(glossy.mirror(img, dirs), reference_bilinear(img, dirs), atol=1e-6)
    np.testing.assert_allclose(glossy.mirror(glossy.mip_levels(img), dirs), reference_bilinear(img, dirs), atol=1e-6)


@pytest.mark.parametrize("rough", (0.05, 0.5, 1.0))
def test_constant_environment_gives_itself(rough):
    env = np.full((32, 64, 3), [2.0, 1.0, 0.5], np.float32)
    r = np.vstack([random_directions(30, 7), [[0, 0, 1], [0, 0, -1]]])
    const = np.broadcast_to([2.0, 1.0, 0.5], (32, 3))
    np.testing.assert_allclose(glossy.glossy_ring(glossy.mip_levels(env), r, rough), const, rtol=1e-5)
    np.testing.assert_allclose(glossy.glossy_mc(env, r, rough, 64, rng=0), const, rtol=1e-5)


# paper's rule: the mip box filter widens the lobe, shrinking the z slope; lod_bias -1 mostly removes that
@pytest.mark.parametrize("rough,tol_ring,tol_bias", [(0.01, 1e-3, 1e-3), (0.1, 3e-3, 1e-3), (0.2, 8e-3, 1e-3),
                                                     (0.5, 0.03, 4e-3)])
def test_linear_environment_matches_closed_form(rough, tol_ring, tol_bias):
    # mean of w.z under the cos^n lobe about r over its hemisphere = r.z (n + 1) / (n + 2)
    tint = np.array([1.0, 0.5, -0.5])
    env = linear_env(64, tint)
    levels = glossy.mip_levels(env)
    r = np.vstack([random_directions(40, 8), [[0, 0, 1], [0, 0, -1], [1, 0, 0]]])
    n = glossy.phong_exponent(rough)
    exact = 1.0 + r[:, 2:3] * (n + 1) / (n + 2) * tint
    ring = glossy.glossy_ring(levels, r, rough)
    assert np.abs(ring - exact).max() < tol_ring
    biased = glossy.glossy_ring(levels, r, rough, glossy.ring_pattern(rough, 64, lod_bias=-1.0))
    assert np.abs(biased - exact).max() < tol_bias
    assert np.abs(glossy.glossy_mc(env, r, rough, 1024, rng=1) - exact).max() < 1.5e-3
    if rough >= 0.1:  # the lobe matters: a mirror lookup is far off
        assert np.abs(glossy.mirror(levels, r) - exact).max() > 3 * tol_bias


@pytest.mark.parametrize("rough", (0.1, 0.5))
def test_filtered_importance_sampling_matches_closed_form_and_constant(rough):
    """FIS (the ring's equal-cost competitor) is exact on a constant map and, with many samples (fine
    levels), converges to the closed form on the linear map; with 36 it stays near it (prefiltering)."""
    env = np.full((32, 64, 3), [2.0, 1.0, 0.5], np.float32)
    r = np.vstack([random_directions(30, 7), [[0, 0, 1], [0, 0, -1]]])
    np.testing.assert_allclose(glossy_fis(glossy.mip_levels(env), r, rough, 36, rng=0),
                               np.broadcast_to([2.0, 1.0, 0.5], (32, 3)), rtol=1e-5)
    tint = np.array([1.0, 0.5, -0.5])
    levels = glossy.mip_levels(linear_env(64, tint))
    n = glossy.phong_exponent(rough)
    exact = 1.0 + r[:, 2:3] * (n + 1) / (n + 2) * tint
    assert np.abs(glossy_fis(levels, r, rough, 2048, rng=1) - exact).max() < 5e-3
    assert np.abs(glossy_fis(levels, r, rough, 36, rng=1) - exact).max() < 0.1
    with pytest.raises(ValueError):
        glossy_fis(levels, r, rough, 0)


def test_glossy_ring_converges_to_mirror():
    env = ndimage.gaussian_filter(rand_env(64, 9), sigma=(2, 2, 0), mode="wrap")
    levels = glossy.mip_levels(env)
    r = random_directions(50, 10)
    mirror = glossy.mirror(levels, r)
    err = [np.abs(glossy.glossy_ring(levels, r, rough) - mirror).max() for rough in (0.1, 0.03, 0.01, 0.002)]
    assert np.all(np.diff(err) < 0) and err[-1] < 2e-3


def test_bad_inputs_raise():
    env = rand_env(8)
    with pytest.raises(ProbelessError):
        glossy.glossy_ring(env, np.array([0.0, 0.0, 1.0]), 0.1)  # not (N, 3)
    with pytest.raises(ProbelessError):
        glossy.glossy_mc(env, np.zeros((2, 3)), 0.1)  # zero-length
    with pytest.raises(ProbelessError):
        glossy.glossy_mc(env, np.ones((2, 3)), 0.1, n_samples=0)
    with pytest.raises(ProbelessError):
        glossy.glossy_ring(env, np.ones((2, 3)), 1.5)
    with pytest.raises(ProbelessError):
        glossy.sample_equirect([env], np.ones((4, 2)), 0)
    with pytest.raises(ProbelessError):
        glossy.sample_equirect([env], np.ones((4, 3)), np.zeros(3))
    with pytest.raises(ProbelessError):
        glossy.ring_pattern(0.1, 64, spacing="spiral")


def test_evaluation_cli_and_figure(tmp_path, capsys):
    path = tmp_path / "smooth.hdr"
    env = ndimage.gaussian_filter(linear_env(32) + rand_env(32, 11), sigma=(1, 1, 0), mode="wrap")
    assert cv2.imwrite(str(path), np.abs(env[..., ::-1]).astype(np.float32))
    res = evaluate_glossy([str(path)], roughness=(0.1, 0.5), n_dirs=16, mc_samples=256, show_progress=False)
    row = res["panoramas"]["smooth.hdr"]["0.1"]
    assert row["ring"]["mean"] < 0.02 and row["mc_noise"]["mean"] < 0.01 and row["ring_lod_bias_-1"]["mean"] < 0.02
    assert row["mirror"]["mean"] > row["ring_lod_bias_-1"]["mean"]
    assert set(res["summary"]) == {"0.1", "0.5"}
    # equal cost: MC and FIS with the ring's 36 lookups, scored against the same converged reference
    assert row["lookups"] == res["settings"]["ring_samples"] == 36
    assert "36 lookups" in row["glossy_equal_cost_reference"]
    assert row["mc_equal"]["mean"] > row["mc_noise"]["mean"]  # 36 samples are far noisier than the reference
    assert 0 < row["glossy_equal_cost_error_ratio"] and res["summary"]["0.5"]["glossy_equal_cost_error_ratio"] > 0
    parser = argparse.ArgumentParser()
    add_evaluation(parser.add_subparsers(), "glossy")
    ns = parser.parse_args(["glossy", "--json", "--panorama", str(path), "--dirs", "4", "--mc-samples", "64",
                            "--no-progress", "--figure", str(tmp_path / "fig.png"), "--figure-size", "24",
                            "--figure-mc-samples", "16"])
    assert ns.func(ns) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["summary"]) == {"0.01", "0.05", "0.1", "0.2", "0.5"}
    fig = cv2.imread(str(tmp_path / "fig.png"))
    assert fig is not None and fig.shape == (20 + 2 * 24, 5 * 24, 3)
    ring, mc = glossy_spheres(np.abs(env), roughness=(0.2,), size=32, mc_samples=128)
    assert ring[0].shape == (32, 32, 3) and ring[0][16, 16].min() > 0 and ring[0][0, 0].max() == 0  # sphere on black
    assert np.abs(ring[0] - mc[0]).mean() < 0.02 * mc[0].mean()  # ring and MC spheres look alike
